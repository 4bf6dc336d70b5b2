"""The servos' goal steps walk the rest lengths (``servo_step_std_ratio``): over one command
period the walk's variance is the spread of a position uniform over the step, ``step^2 / 12``
for the ratio ``1 / sqrt(12)``; none while the goals hold."""

import math

import numpy as np

from gyrohost.estimator import TensegrityEKF
from gyrohost.estimator.config import EstimatorConfig

RATIO, PERIOD_S, STEP_M = 1.0 / math.sqrt(12.0), 0.01, 1e-3


def _ekf(model, ratio=RATIO):
    ekf = TensegrityEKF(model, EstimatorConfig(servo_step_std_ratio=ratio, rest_psd_m2_s=0.0))
    rest = model.input_at(0.0)[: model.alpha]
    ekf.set_input(rest, 0.0)
    return ekf, rest


def _rest_noise(ekf, dt):
    r = ekf.layout.rest
    return np.diag(ekf.process.noise(dt))[r]


def test_a_period_s_walk_is_the_spread_of_a_position_uniform_over_the_step(model):
    ekf, rest = _ekf(model)
    ekf.set_input(rest + [STEP_M, -2 * STEP_M], PERIOD_S)
    ekf.advance(PERIOD_S)
    uniform = np.random.default_rng(3).uniform(0.0, 1.0, (1_000_000, 1)) * [STEP_M, 2 * STEP_M]
    over_period = _rest_noise(ekf, PERIOD_S / 4) * 4  # the walk over the period, in 4 steps
    np.testing.assert_allclose(over_period, uniform.var(axis=0), rtol=5e-3)


def test_no_walk_while_the_goals_hold_or_without_the_key(model):
    ekf, rest = _ekf(model)
    ekf.set_input(rest + STEP_M, PERIOD_S)
    ekf.set_input(rest + STEP_M, 2 * PERIOD_S)
    ekf.advance(2 * PERIOD_S)
    assert np.all(_rest_noise(ekf, PERIOD_S) == 0.0)
    ekf, rest = _ekf(model, ratio=0.0)
    ekf.set_input(rest + STEP_M, PERIOD_S)
    ekf.advance(PERIOD_S)
    assert np.all(_rest_noise(ekf, PERIOD_S) == 0.0)


def test_a_late_goal_spreads_its_step_over_the_longer_period(model):
    ekf, rest = _ekf(model)
    ekf.set_input(rest + STEP_M, 2 * PERIOD_S)
    ekf.advance(2 * PERIOD_S)
    np.testing.assert_allclose(_rest_noise(ekf, PERIOD_S), STEP_M**2 / 12 / 2, rtol=1e-12)
