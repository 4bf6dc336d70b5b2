"""Pruning never changes the answer: wheels spun up by a controller or by ``Stepper.step(u)``
get their gyroscopic forces, and a term left out on the caller's word raises when needed."""

from pathlib import Path

import numpy as np
import pytest

import gyrotensegrity
from gyrotensegrity import Model, PrunedTermError, Stepper, load_scene, scene_from_dict, simulate
from gyrotensegrity.compat import tomllib
from gyrotensegrity.fast import FastDynamics

SCENES = Path(gyrotensegrity.__file__).parent / "scenes"
SPIN_UP_S = 0.5
SIGNS = (1.0, -1.0, -1.0, 1.0)  # the dbar-gyro spin pattern


def nospin_data():
    return tomllib.loads((SCENES / "dbar-nospin.toml").read_text())


def spun_up_data():
    """dbar-nospin with its torque-driven wheels spun up to about 75 rad/s in the scene itself
    (a torque step over the first 0.5 s): the model of this scene builds every term it needs."""
    data = nospin_data()
    for bar, sign in zip(data["bars"], SIGNS, strict=True):
        w = bar["wheel"]
        j3 = 0.5 * w["mass"] * w["radius"] ** 2
        torque = sign * 75.0 * j3 / SPIN_UP_S
        w["torque"] = {"t": [0.0, SPIN_UP_S, SPIN_UP_S + 1e-9], "value": [torque, torque, 0.0]}
    return data


@pytest.fixture(scope="module")
def at_rest():
    """The wheels at rest in the scene, torque 0: only a controller or the caller spins them."""
    return Model(scene_from_dict(nospin_data(), "dbar-nospin"))


@pytest.fixture(scope="module")
def scheduled():
    return Model(scene_from_dict(spun_up_data(), "dbar-nospin, spun up in the scene"))


def peak_z(N):
    return float(np.abs(N[..., 2, :]).max())


def test_every_wheel_keeps_the_gyroscopic_term(at_rest):
    assert "gyroscopic" in at_rest.terms
    assert "gyroscopic" in Model(load_scene(SCENES / "dbar-gyro.toml")).terms


@pytest.mark.parametrize("fast", [False, True])
def test_control_callback_spin_up_equals_the_scheduled_spin_up(at_rest, scheduled, fast):
    def control(t, x, u, params):
        return scheduled.input_at(t)  # the same torques, from a controller

    opts = dict(duration=0.8, integrator="rk4", dt=2e-3, sample_dt=0.02, fast=fast)
    driven = simulate(at_rest, control=control, **opts)
    reference = simulate(scheduled, **opts)
    assert peak_z(reference["N"]) > 0.002  # the spun-up wheels tilt the plane (0 without the term)
    np.testing.assert_allclose(driven["N"], reference["N"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(driven["omega_w"], reference["omega_w"], rtol=1e-12)


@pytest.mark.parametrize("fast", [False, True])
def test_stepper_inputs_spin_up_equals_the_scheduled_spin_up(at_rest, scheduled, fast):
    driven = Stepper(at_rest, max_dt=2e-3, fast=fast)
    reference = Stepper(scheduled, max_dt=2e-3, fast=fast)
    for _ in range(40):
        driven.step(0.02, scheduled.input_at(driven.t))
        reference.step(0.02)
    assert peak_z(reference.nodes()[0]) > 0.002
    np.testing.assert_allclose(driven.x, reference.x, rtol=0, atol=1e-12)


@pytest.mark.parametrize("fast", [False, True])
def test_omitted_term_raises_when_a_wheel_is_driven(scheduled, fast):
    pruned = Model(scene_from_dict(nospin_data(), "dbar-nospin"), omit=("gyroscopic",))
    assert "gyroscopic" not in pruned.terms
    u = scheduled.input_at(0.0)
    with pytest.raises(PrunedTermError, match=r"wheel of bar b12 .*omit=\('gyroscopic',\)") as exc:
        Stepper(pruned, fast=fast).step(0.01, u)
    assert (exc.value.term, exc.value.member) == ("gyroscopic", "b12")
    with pytest.raises(PrunedTermError, match="b12 has an input of"):
        simulate(pruned, duration=0.1, control=lambda t, x, u, p: u + (t > 0.05) * 1e-3, fast=fast)


def test_omitted_term_raises_for_a_spinning_state_and_batch(scheduled):
    pruned = Model(scene_from_dict(nospin_data(), "dbar-nospin"), omit=("gyroscopic",))
    with pytest.raises(PrunedTermError, match="b23 spins at -5 rad/s"):
        pruned.state(*pruned.nodes(pruned.initial_state()), omega=[0.0, -5.0, 0.0, 0.0])
    fd = FastDynamics(pruned)
    q = np.zeros((2, 3, fd.size))
    with pytest.raises(PrunedTermError, match="b41"):
        fd.accelerations(q, q, np.array([[0, 0, 0, 0], [0, 0, 0, 1e-3]]), pruned.input_at(0)[:2])


def test_omitted_term_unused_gives_the_full_model(at_rest):
    pruned = Model(scene_from_dict(nospin_data(), "dbar-nospin"), omit=("gyroscopic",))
    a = simulate(pruned, duration=0.5, integrator="rk4", dt=2e-3, fast=True)
    b = simulate(at_rest, duration=0.5, integrator="rk4", dt=2e-3, fast=True)
    np.testing.assert_array_equal(a["N"], b["N"])


def test_omit_refused_for_a_scene_that_spins_and_for_unknown_terms():
    with pytest.raises(PrunedTermError, match="b12 spins at 74.87"):
        Model(load_scene(SCENES / "dbar-gyro.toml"), omit=("gyroscopic",))
    with pytest.raises(PrunedTermError, match=r"b12 has a scheduled input of 0.0036\d* N m"):
        Model(scene_from_dict(spun_up_data(), "spun up"), omit=("gyroscopic",))
    with pytest.raises(ValueError, match="'gravity' cannot be omitted"):
        Model(scene_from_dict(nospin_data(), "dbar-nospin"), omit=("gravity",))
