"""The servos' goal steps spread the rest lengths about their lag (``servo_step_std_ratio``):
until the next goal they keep the spread of a position uniform over the step, ``step^2 / 12``
for the ratio ``1 / sqrt(12)``, whatever the filter's steps; none while the goals hold, and
the first goals set the lag's target without a step."""

import math

import numpy as np
import pytest

from gyrohost.estimator import TensegrityEKF
from gyrohost.estimator.config import EstimatorConfig

RATIO, PERIOD_S, STEP_M = 1.0 / math.sqrt(12.0), 0.01, 1e-3
LAG_S = 0.005  # the simulated rig's: shorter than the command period


def _ekf(model, ratio=RATIO):
    config = EstimatorConfig(servo_step_std_ratio=ratio, rest_psd_m2_s=0.0, servo_lag_s=LAG_S)
    ekf = TensegrityEKF(model, config)
    rest = model.input_at(0.0)[: model.alpha]
    ekf.set_input(rest, 0.0)
    return ekf, rest


def _rest_noise(ekf, dt):
    r = ekf.layout.rest
    return np.diag(ekf.process.noise(dt))[r]


@pytest.mark.parametrize("steps", [1, 4], ids=["one step", "four steps"])
def test_the_rest_lengths_keep_the_spread_of_a_position_uniform_over_the_step(model, steps):
    ekf, rest = _ekf(model)
    ekf.P[:] = 0.0  # only the step's spread from here on
    ekf.set_input(rest + [STEP_M, -2 * STEP_M], PERIOD_S)
    ekf.advance(PERIOD_S)
    for k in range(1, 5 * steps + 1):  # five lags: the spread settles
        ekf.advance(PERIOD_S + k * PERIOD_S / steps)
    uniform = np.random.default_rng(3).uniform(0.0, 1.0, (1_000_000, 1)) * [STEP_M, 2 * STEP_M]
    r = ekf.layout.rest
    np.testing.assert_allclose(np.diag(ekf.P)[r], uniform.var(axis=0), rtol=5e-3)


def test_no_spread_while_the_goals_hold_or_without_the_key(model):
    ekf, rest = _ekf(model)
    ekf.set_input(rest + STEP_M, PERIOD_S)
    ekf.set_input(rest + STEP_M, 2 * PERIOD_S)
    ekf.advance(2 * PERIOD_S)
    assert np.all(_rest_noise(ekf, PERIOD_S) == 0.0)
    ekf, rest = _ekf(model, ratio=0.0)
    ekf.set_input(rest + STEP_M, PERIOD_S)
    ekf.advance(PERIOD_S)
    assert np.all(_rest_noise(ekf, PERIOD_S) == 0.0)


def test_the_first_goals_are_no_step(model):
    ekf = TensegrityEKF(model, EstimatorConfig(servo_step_std_ratio=RATIO, rest_psd_m2_s=0.0))
    ekf.set_input(model.input_at(0.0)[: model.alpha] + STEP_M, 0.0)
    ekf.advance(PERIOD_S)
    assert np.all(_rest_noise(ekf, PERIOD_S) == 0.0)
