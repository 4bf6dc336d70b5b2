"""Free-floating scenes: angular momentum (always) and energy (fixed rest lengths, no damping)."""

from pathlib import Path

import numpy as np
import pytest

import gyrotensegrity
from gyrotensegrity import Model, load_scene, simulate

SCENES = Path(gyrotensegrity.__file__).parent / "scenes"

# A minute of the reference equations at tight tolerances on one core: beside the simulated rig's
# real-time tests (tests/conftest.py), whose second core would otherwise idle.
pytestmark = pytest.mark.slow


def relative_drift(series):
    series = np.asarray(series)
    return np.abs(series - series[0]).max() / np.linalg.norm(np.atleast_1d(series[0]))


@pytest.fixture(scope="module", params=[(False, 2.0), (True, 10.0)], ids=["reference", "fast"])
def prism_run(request):
    """The free prism from rest lengths held: the reference equations over 2 s (7.8 s of CPU a
    simulated second at these tolerances), the fast path, the same equations, over 10 s."""
    fast, duration_s = request.param
    model = Model(load_scene(SCENES / "prism-gyro.toml"))
    return duration_s, simulate(model, duration=duration_s, rtol=1e-12, atol=1e-14, fast=fast)


def test_prism_energy_constant(prism_run):
    duration_s, run = prism_run
    assert run["t"][-1] == pytest.approx(duration_s)
    assert relative_drift(run["energy"]) <= 1e-9


def test_prism_angular_momentum_constant(prism_run):
    _, run = prism_run
    assert np.linalg.norm(run["angular_momentum"][0]) > 1e-4  # the wheels carry momentum
    assert relative_drift(run["angular_momentum"]) <= 1e-10


def pumping(t, x, u, params):
    """Rest lengths oscillating by 5 % (a controller with the common callback signature)."""
    return np.concatenate([u[: params.alpha] * (1 + 0.05 * np.sin(7.0 * t)), u[params.alpha :]])


@pytest.mark.parametrize("scene", ["prism-gyro", "prism-string-mass"])
def test_momentum_constant_while_rest_lengths_change(scene):
    model = Model(load_scene(SCENES / f"{scene}.toml"))
    run = simulate(model, duration=1.0, rtol=1e-11, atol=1e-13, control=pumping)
    assert np.ptp(run["rest_length"][:, 0]) > 0.01
    assert relative_drift(run["angular_momentum"]) <= 1e-10


def test_string_mass_energy_constant():
    model = Model(load_scene(SCENES / "prism-string-mass.toml"))
    assert "point_masses" in model.terms
    run = simulate(model, duration=1.5, rtol=1e-12, atol=1e-14)
    assert relative_drift(run["energy"]) <= 1e-9


def test_dbar_momentum_constant_during_maneuver():
    """Class-2 joints, spinning wheels and the n1-n3 string shortening: the multipliers use
    the same J_t and W_T as the dynamics, else momentum would not be kept."""
    model = Model(load_scene(SCENES / "dbar-gyro.toml"))
    run = simulate(model, duration=1.5)
    assert relative_drift(run["angular_momentum"]) <= 1e-10
