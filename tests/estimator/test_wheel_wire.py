"""The wheel board's wire step (``wheel_resolution_rad_s``): commands reach the board rounded to
it, and its telemetry truncates towards zero. The predicted reading's mean is checked against a
Monte Carlo of the truncation, its slope against a difference quotient."""

import numpy as np
import pytest

from gyrohost.estimator import TensegrityEKF
from gyrohost.estimator.config import EstimatorConfig
from gyrohost.estimator.fuse_wheels import predict, truncation
from gyrohost.estimator.layout import layout_of

STEP, STD = 1e-3, 0.0146  # the wire's mrad/s; the emulated telemetry's noise, rad/s


def test_the_wheels_follow_the_command_the_board_was_sent(model):
    config = EstimatorConfig(wheel_lag_s=0.013, wheel_resolution_rad_s=STEP)
    ekf = TensegrityEKF(model, config)
    rest = model.input_at(0.0)[: model.alpha]
    command = np.array([74.87462492, -74.87462492, -74.87462492, 74.87462492])
    ekf.set_input(rest, 0.0, command)
    ekf.advance(0.3)  # 23 lags: the wheels are at their setpoint
    np.testing.assert_allclose(
        ekf.x[layout_of(model).omega], [74.875, -74.875, -74.875, 74.875], atol=1e-9
    )


@pytest.mark.parametrize("omega", [-74.875, -0.004, 0.0, 0.0021, 3.1, 74.875])
def test_the_reading_loses_the_truncation_s_mean(omega):
    config = EstimatorConfig(wheel_resolution_rad_s=STEP, wheel_speed_std_rad_s=STD)
    rng = np.random.default_rng(5)
    readings = np.trunc((omega + STD * rng.standard_normal(2_000_000)) / STEP) * STEP
    noise_mean = STD / np.sqrt(2_000_000)  # the Monte Carlo's own scatter of the mean
    mean, _ = truncation(np.array([omega]), config)
    assert abs(omega + mean[0] - readings.mean()) < 4 * noise_mean
    assert abs(mean[0]) <= STEP / 2


def test_the_slope_is_the_mean_s_derivative():
    config = EstimatorConfig(wheel_resolution_rad_s=STEP, wheel_speed_std_rad_s=STD)
    omega, h = np.array([-0.02, -0.003, 0.0, 0.01, 0.05]), 1e-6
    _, slope = truncation(omega, config)
    quotient = (truncation(omega + h, config)[0] - truncation(omega - h, config)[0]) / (2 * h)
    np.testing.assert_allclose(slope, quotient, rtol=1e-6, atol=1e-12)


def test_without_a_step_the_reading_is_the_state(model):
    ekf = TensegrityEKF(model, EstimatorConfig())
    L = ekf.layout
    hx, H = predict(ekf, ekf.x)
    np.testing.assert_array_equal(hx, ekf.x[L.omega])
    np.testing.assert_array_equal(H[:, L.omega], np.eye(L.n_wheels))
