"""The Stepper (rig truth model) and the compiled model's structure."""

from pathlib import Path

import numpy as np
import pytest

import gyrotensegrity
from gyrotensegrity import Model, Stepper, load_scene, simulate
from gyrotensegrity.dynamics import evaluate

SCENES = Path(gyrotensegrity.__file__).parent / "scenes"


@pytest.fixture(scope="module")
def dbar():
    return Model(load_scene(SCENES / "dbar-gyro.toml"))


def test_svd_of_P_reassembles(dbar):
    P = dbar.structure.P.toarray()
    assert np.allclose(dbar.U1.toarray() * dbar.sigma1 @ dbar.V.toarray().T, P, atol=1e-14)
    U = np.hstack([dbar.U1.toarray(), dbar.U2.toarray()])
    assert np.allclose(U.T @ U, np.eye(dbar.n), atol=1e-14)


def test_accelerations_keep_constraints(dbar):
    """At a perturbed state: joints accelerate together and b.b_ddot = -|b_dot|^2."""
    rng = np.random.default_rng(1)
    x = dbar.initial_state()
    x[dbar.layout.q_dot] = rng.normal(scale=0.3, size=3 * dbar.m)
    from gyrotensegrity.projection import project_velocities

    x = project_velocities(dbar, x)
    ev = evaluate(0.0, x, dbar.input_at(1.0), dbar)
    st = dbar.structure
    assert np.abs(ev.N_ddot @ st.P.toarray()).max() < 1e-12
    B = ev.N[:, st.bar_end] - ev.N[:, st.bar_start]
    Bd = ev.N_dot[:, st.bar_end] - ev.N_dot[:, st.bar_start]
    Bdd = ev.N_ddot[:, st.bar_end] - ev.N_ddot[:, st.bar_start]
    np.testing.assert_allclose(np.sum(B * Bdd, 0), -np.sum(Bd * Bd, 0), atol=1e-12)


def test_stepper_matches_simulate_rk4(dbar):
    u = dbar.pack_input([0.40, 0.46], [70.0, -80.0, -75.0, 75.0])
    run = simulate(dbar, duration=0.1, integrator="rk4", dt=1e-3, control=lambda t, x, u0, p: u)
    stepper = Stepper(dbar, max_dt=1e-3)
    for _ in range(10):
        stepper.step(0.01, u)
    N, _ = stepper.nodes()
    assert np.abs(N - run["N"][-1]).max() < 1e-14
    assert np.abs(N[:, :4] - dbar.structure.N0[:, :4]).max() > 1e-4  # it moved


def test_pack_input_checks_size(dbar):
    with pytest.raises(ValueError, match="2 rest lengths and 4 wheel inputs"):
        dbar.pack_input([0.4], [1.0])
