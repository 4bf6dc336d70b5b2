"""The weighed masses' rounding in the sigmas of the parameters that scale with them."""

import numpy as np
import pytest

from gyrohost.config import load_rig_config
from gyrohost.ident.fit import FitResult
from gyrohost.ident.params import Param
from gyrohost.ident.report import report_lines
from gyrohost.ident.weighing import mass_sigma, with_weighing
from gyrohost.resources import resolve
from gyrotensegrity import load_scene


@pytest.fixture(scope="module")
def scene():
    return load_scene(load_rig_config(resolve("config", "sim-rig")).scene_path)


def result_of(scene, groups, sigma):
    params = [Param(g, g, g != "mounting", 1.0, "") for g in groups]
    n = len(params)
    return FitResult(
        params, np.zeros(n), np.array(sigma, float), np.eye(n), [], np.ones(n, bool), [], None,
        [], [], {}, 0.0, 0, "", scene, 0.0,
    )  # fmt: skip


def test_a_bar_and_wheel_weighed_to_a_gram_are_known_to_their_readings_rounding(scene):
    bar = scene.bars[0]
    moving_kg = bar.mass + bar.wheel.mass  # the D-bar's bars are alike
    assert mass_sigma(scene, 1e-3) == pytest.approx(np.sqrt(2 / 12) * 1e-3 / moving_kg)
    assert mass_sigma(scene, 0.0) == 0.0


def test_the_weighing_widens_only_what_scales_with_the_masses(scene):
    result = result_of(
        scene, ["J3", "stiffness", "damping", "mounting"], [0.002, 0.05, np.inf, 0.01]
    )
    rel = mass_sigma(scene, 1e-3)
    weighed = with_weighing(result, 1e-3)
    assert weighed.sigma[0] == pytest.approx(np.hypot(0.002, rel))
    assert weighed.sigma[1] == pytest.approx(np.hypot(0.05, rel))
    assert np.isinf(weighed.sigma[2]) and weighed.sigma[3] == 0.01
    assert weighed.weighing_sigma == rel
    assert any("weighed masses' " in line for line in report_lines(weighed))
    assert not any("weighed" in line for line in report_lines(result))


def test_fitted_masses_or_exact_ones_add_nothing(scene):
    result = result_of(scene, ["J3", "bar-mass"], [0.002, 0.01])
    assert with_weighing(result, 1e-3) is result
    assert with_weighing(result_of(scene, ["J3"], [0.002]), 0.0).weighing_sigma == 0.0
