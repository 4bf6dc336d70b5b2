"""The wheel board's reported speed trails the wheel through the firmware's low-pass
(``wheel_filter_s``), and the time the board acts on a command is uncertain
(``wheel_command_time_std_s``): the wheel states stay the wheels' own speeds. The reference is
the board's tick loop written out here (setpoint ramp, motor lag, the firmware's
``y += (x - y) / 2^shift`` per 1 ms tick)."""

import math

import numpy as np
import pytest
from wheel_step import ACCEL, STEP, TAU_S, stepped_filter

from gyrohost.estimator.config import SPEED_FILTER_DELAY_S, EstimatorConfig
from gyrohost.estimator.fuse_wheels import predict

TICK_S, SHIFT = 1e-3, 3  # the firmware's tick, s, and its SPEED_FILTER_SHIFT


def board(t_end_s, s0):
    """Setpoint, wheel speed and reported speed (rad/s) at every 1 ms tick up to ``t_end_s``
    after a command from ``s0`` to ``s0 + STEP`` (a wheel that turns the positive way)."""
    s = w = y = s0
    out = {}
    for k in range(1, int(round(t_end_s / TICK_S)) + 1):
        s = min(s + ACCEL * TICK_S, s0 + STEP)
        w = s + (w - s) * math.exp(-TICK_S / TAU_S)
        y += (w - y) / 2**SHIFT
        out[k] = (s, w, y)
    return out


def reported_error(model, **keys):
    """Largest |predicted report - the board's report| (rad/s) over 0.4 s of a step."""
    ekf, omega, s0 = stepped_filter(model, **keys)
    ticks = board(0.4, 0.0)
    worst = 0.0
    for k in range(10, 401, 10):
        ekf.advance(k * TICK_S)
        hx, _ = predict(ekf, ekf.x)
        want = s0 + np.sign(s0) * ticks[k][2]
        worst = max(worst, float(np.max(np.abs(hx - want))))
    return worst


def test_the_filter_delay_is_the_firmware_low_pass_lag_of_a_ramp():
    ticks = board(0.1, 0.0)
    s, w, y = ticks[100]  # mid-ramp, long after the ramp started: a steady change
    w_dot = (s - w) / TAU_S
    assert (w - y) / w_dot == pytest.approx(SPEED_FILTER_DELAY_S, rel=0.02)


def test_the_predicted_report_follows_the_board_through_a_speed_step(model):
    with_filter = reported_error(model, wheel_filter_s=SPEED_FILTER_DELAY_S)
    without = reported_error(model)
    # the approximation omega - tau_f omega_dot misses up to 0.06 rad/s where the ramp starts
    # and ends, the board's ramp in 1 ms steps 0.03 more
    assert with_filter < 0.1, with_filter
    assert without > 0.5, without  # the report trails the wheel by 7 ms at 100 rad/s^2


def test_the_report_jacobian_is_its_derivative(model):
    ekf, omega, _ = stepped_filter(model, wheel_filter_s=SPEED_FILTER_DELAY_S)
    ekf.advance(0.05)  # mid-ramp
    _, H = predict(ekf, ekf.x)
    eps = 1e-4
    for col in range(ekf.x.size):
        dx = np.zeros_like(ekf.x)
        dx[col] = eps
        numeric = (predict(ekf, ekf.x + dx)[0] - predict(ekf, ekf.x - dx)[0]) / (2.0 * eps)
        np.testing.assert_allclose(H[:, col], numeric, atol=1e-6, err_msg=f"state {col}")


def test_the_command_time_spreads_the_wheels_while_they_change_speed(model):
    std = 0.0015
    ekf, omega, _ = stepped_filter(model, wheel_command_time_std_s=std)
    w = np.arange(omega.start, omega.stop)
    steady = ekf.process.noise(0.01, None, ekf.x)[w, w]  # commanded, not yet acted on
    ekf.advance(0.05)
    ramping = ekf.process.noise(0.01, None, ekf.x)[w, w]
    rate = ekf.process.wheel_acceleration(ekf.x[None, omega], ekf.u)[0]
    assert np.all(np.abs(rate) > 50.0)  # mid-ramp
    np.testing.assert_allclose(ramping - steady, 2.0 * (std * rate) ** 2 / TAU_S * 0.01)
    ekf.advance(1.0)  # settled: the walk is gone
    settled = ekf.process.noise(0.01, None, ekf.x)[w, w]
    np.testing.assert_allclose(settled, EstimatorConfig().wheel_accel_psd_rad2_s3 * 0.01)
