"""The weighed masses' rounding in the sigmas of the parameters that scale with them."""

from types import SimpleNamespace

import numpy as np
import pytest

from gyrohost.config import load_rig_config
from gyrohost.ident import weighing
from gyrohost.ident.fit import FitResult
from gyrohost.ident.params import Param
from gyrohost.ident.report import report_lines
from gyrohost.ident.weighing import bar_mass_sensitivity, weighing_sigma, with_weighing
from gyrohost.resources import resolve
from gyrotensegrity import load_scene


@pytest.fixture(scope="module")
def scene():
    return load_scene(load_rig_config(resolve("config", "sim-rig")).scene_path)


def result_of(scene, groups, sigma, sensitivity):
    params = [Param(g, g, g != "mounting", 1.0, "") for g in groups]
    n = len(params)
    return FitResult(
        params, np.zeros(n), np.array(sigma, float), np.eye(n), [], np.ones(n, bool), [], None,
        [], [], {}, 0.0, 0, "", scene, 0.0, mass_sensitivity=sensitivity,
    )  # fmt: skip


def test_a_reading_to_a_gram_is_known_to_its_rounding_shared_by_bar_and_wheel(scene):
    bar, wheel = scene.bars[0].mass, scene.bars[0].wheel.mass  # the D-bar's bars are alike
    reading = 1e-3 / np.sqrt(12.0)
    s = np.array([1.0, 0.0, 0.7])
    expected = [
        reading / bar,
        reading / wheel,
        np.hypot(0.7 * reading / bar, 0.3 * reading / wheel),
    ]
    np.testing.assert_allclose(weighing_sigma(scene, s, 1e-3), expected, rtol=1e-12)


def test_the_weighing_widens_only_what_scales_with_the_masses(scene):
    sigma = [0.002, 0.05, np.inf, 0.01]
    s = np.array([0.8, 1.0, 1.0, 0.3])
    result = result_of(scene, ["J3", "stiffness", "damping", "mounting"], sigma, s)
    weighed = with_weighing(result, 1e-3)
    added = weighing_sigma(scene, s, 1e-3)
    assert weighed.sigma[0] == pytest.approx(np.hypot(0.002, added[0]))
    assert weighed.sigma[1] == pytest.approx(np.hypot(0.05, added[1]))
    assert np.isinf(weighed.sigma[2]) and weighed.sigma[3] == 0.01
    line = next(line for line in report_lines(weighed) if "weighing" in line)
    assert f"J3 {100 * added[0]:.2f} %" in line and "mounting" not in line
    assert not any("weighing" in line for line in report_lines(result))


def test_masses_not_taken_as_weighed_or_exact_add_nothing(scene):
    fitted = result_of(scene, ["J3", "bar-mass"], [0.002, 0.01], None)
    assert with_weighing(fitted, 1e-3) is fitted
    exact = result_of(scene, ["J3"], [0.002], np.ones(1))
    assert with_weighing(exact, 0.0) is exact


def test_the_sensitivity_is_the_linear_fits_response_to_the_bar_mass(monkeypatch):
    """A linear residual ``A theta + b log m - y``: the optimum moves by ``-A^+ b`` per unit of
    the log mass."""
    rng = np.random.default_rng(3)
    A, b = rng.normal(size=(20, 3)), rng.normal(size=20)
    bar_mass = Param("bar_mass", "bar-mass", True, 0.1, "kg", step=0.03)
    monkeypatch.setattr(weighing, "parameters", lambda *args: [bar_mass])
    extended = lambda theta: A @ theta[:3] + b * theta[3]  # noqa: E731
    problem = SimpleNamespace(
        scene=None, config=None, servo_lag_s=0.0, params=[], with_params=lambda p: extended
    )
    s = bar_mass_sensitivity(problem, np.zeros(3), A)
    np.testing.assert_allclose(s, -np.linalg.pinv(A) @ b, rtol=1e-10)
