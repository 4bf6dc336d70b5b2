"""The closed-form Jacobian of the fast path (gyrotensegrity.fast_jacobian, numpy and compiled)
against the complex step through the fast path's batched accelerations, at states along each
scene's manoeuvre with strings taut and slack."""

from pathlib import Path

import numpy as np
import pytest

import gyrotensegrity
from gyrotensegrity import Model, Stepper, load_scene
from gyrotensegrity.fast import FastDynamics
from gyrotensegrity.fast_jacobian import FastJacobian, JacobianUnsupported

SCENES = sorted(  # the paper's model: the fast path refuses the rig-fidelity option
    p for p in (Path(gyrotensegrity.__file__).parent / "scenes").glob("*.toml")
    if load_scene(p).rig is None and load_scene(p).bars
)  # fmt: skip
TOL = 1e-8  # relative to the largest entry of the Jacobian
STEP = 1e-20


@pytest.fixture(scope="module", params=[p.stem for p in SCENES])
def model(request):
    return Model(load_scene(SCENES[[p.stem for p in SCENES].index(request.param)]))


def manoeuvre_points(model, count=12, seed=0):
    """(q, q_dot, omega_w, rest) at ``count`` times along the scene's manoeuvre (RK4 at 2 ms),
    wheels spun at random, rest lengths scaled by 0.9-1.1 (slack and taut)."""
    rng = np.random.default_rng(seed)
    stepper, L, m = Stepper(model, max_dt=2e-3, fast=True), model.layout, model.m
    dt = min(model.scene.duration, 3.0) / count
    for _ in range(count):
        stepper.step(dt)
        x, u = stepper.x, model.input_at(stepper.t)
        omega = rng.normal(scale=100.0, size=len(model.wheel_bars))
        rest = u[: model.alpha] * rng.uniform(0.9, 1.1, model.alpha)
        yield x[L.q].reshape(3, m), x[L.q_dot].reshape(3, m), omega, rest


def complex_step(dyn, q, q_dot, omega, rest):
    """The Jacobian (3 m, 6 m + n_w + alpha) by the complex step through the batched path."""
    x = np.concatenate([q.ravel(), q_dot.ravel(), omega, rest])
    D, n, nw = x.size, q.size, omega.size
    X = np.tile(x.astype(complex), (D, 1))
    X[np.arange(D), np.arange(D)] += 1j * STEP
    m = q.shape[1]
    z, _ = dyn.accelerations(
        X[:, :n].reshape(D, 3, m),
        X[:, n : 2 * n].reshape(D, 3, m),
        X[:, 2 * n : 2 * n + nw],
        X[:, 2 * n + nw :],
    )
    return z[0].real.ravel(), z.reshape(D, n).imag.T / STEP


def taut(dyn, q, q_dot, rest):
    """Which strings pull (alpha,) bool, by the fast path's own rule."""
    Y = (q @ dyn.EE_T.A + dyn.off)[:, dyn.beta :]
    Y_dot = (q_dot @ dyn.EE_T.A)[:, dyn.beta :]
    s = np.sqrt((Y * Y).sum(axis=0))
    tension = dyn.k_s * (s - rest) + dyn.c_s * (Y * Y_dot).sum(axis=0) / s
    return (s > rest) & (tension > 0.0)


@pytest.mark.parametrize("kernel", [True, False], ids=["kernel", "numpy"])
def test_closed_form_equals_complex_step_along_the_manoeuvre(model, kernel):
    dyn = FastDynamics(model)
    jac = FastJacobian(dyn, kernel=kernel)
    assert (jac.kernel is not None) == (kernel and dyn.kernel is not None)
    seen = []
    for q, q_dot, omega, rest in manoeuvre_points(model):
        z_ref, J_ref = complex_step(dyn, q, q_dot, omega, rest)
        z, J = jac(q, q_dot, omega, rest)
        assert J.shape == (3 * model.m, 6 * model.m + len(omega) + model.alpha)
        assert np.abs(z.ravel() - z_ref).max() <= 1e-12 * np.abs(z_ref).max()
        assert np.abs(J - J_ref).max() <= TOL * np.abs(J_ref).max()
        seen.append(taut(dyn, q, q_dot, rest))
    seen = np.array(seen)
    if model.alpha:
        assert seen.any() and not seen.all(), "the states should hold taut and slack strings"


def test_slack_string_has_no_rest_length_column():
    model = Model(load_scene(SCENES[0]))
    dyn = FastDynamics(model)
    q, q_dot, omega, rest = next(manoeuvre_points(model, count=4))
    rest = rest.copy()
    rest[0] = 10.0  # far longer than the string: slack
    _, J = FastJacobian(dyn)(q, q_dot, omega, rest)
    assert np.all(J[:, 6 * model.m + len(omega)] == 0.0)
    assert np.any(J[:, -1] != 0.0) or not taut(dyn, q, q_dot, rest)[-1]


@pytest.mark.parametrize("options", [{"dense_limit": 0}, {"coordinates": "full"}])
def test_unsupported_variants_are_refused(options):
    model = Model(load_scene(SCENES[0]))  # the D-bar: joints, so full coordinates need them
    assert model.c > 0
    with pytest.raises(JacobianUnsupported, match="complex step"):
        FastJacobian(FastDynamics(model, **options))


@pytest.mark.parametrize(
    "scene", [p for p in SCENES if Model(load_scene(p)).c == 0], ids=lambda p: p.stem
)
def test_full_coordinates_of_a_joint_free_structure(scene):
    model = Model(load_scene(scene))
    dyn = FastDynamics(model, coordinates="full")
    jac = FastJacobian(dyn)
    rng = np.random.default_rng(5)
    L, n = model.layout, model.n
    for q, q_dot, omega, rest in manoeuvre_points(model, count=4):
        x = model.initial_state()
        x[L.q], x[L.q_dot] = q.ravel(), q_dot.ravel()
        N = dyn.from_reduced(x)
        Q, Q_dot = N[: 3 * n].reshape(3, n), N[3 * n : 6 * n].reshape(3, n)
        Q_dot = Q_dot + rng.normal(scale=0.1, size=Q_dot.shape)
        _, J_ref = complex_step(dyn, Q, Q_dot, omega, rest)
        _, J = jac(Q, Q_dot, omega, rest)
        assert J.shape == (3 * n, 6 * n + len(omega) + model.alpha)
        assert np.abs(J - J_ref).max() <= TOL * np.abs(J_ref).max()
