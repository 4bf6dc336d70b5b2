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
    after a command from ``s0`` to ``s0 + STEP`` at 0 (a wheel that turns the positive way), in
    the firmware's order: the wheel has turned under the last tick's setpoint, the encoder's
    count difference is that tick's mean speed, then the setpoint ramps."""
    s = w = y = s0
    out = {}
    for k in range(1, int(round(t_end_s / TICK_S)) + 1):
        w_end = s + (w - s) * math.exp(-TICK_S / TAU_S)
        y += ((w + w_end) / 2.0 - y) / 2**SHIFT
        w = w_end
        s = min(s + ACCEL * TICK_S, s0 + STEP)
        out[k] = (s, w, y)
    return out


def reported_misses(model, **keys):
    """|predicted report - the board's report| (rad/s) every 10 ms over 0.4 s of a step and the
    std the fusion adds for the low-pass's curvature there, each (n_w,). The command comes
    half a tick before the tick that takes it (a frame's mean place in a tick)."""
    ekf, omega, s0 = stepped_filter(model, **keys)
    ticks = board(0.4, 0.0)
    misses, curves = [], []
    for k in range(10, 401, 10):
        ekf.advance((k - 0.5) * TICK_S)
        hx, _ = predict(ekf, ekf.x)
        misses.append(np.abs(hx - (s0 + np.sign(s0) * ticks[k][2])))
        jerk = ekf.process.wheel_jerk(ekf.process.wheel_acceleration(ekf.x[None, omega], ekf.u)[0])
        curves.append(np.abs(ekf.config.wheel_filter_s**2 * jerk))
    return np.array(misses), np.array(curves)


def reported_error(model, **keys):
    """Largest |predicted report - the board's report| (rad/s) over 0.4 s of a step."""
    return float(reported_misses(model, **keys)[0].max())


def test_the_filter_delay_is_the_firmware_low_pass_lag_of_a_ramp():
    """A wheel speeding up steadily: each tick's count difference is the tick's mean speed,
    which the firmware's low-pass filters; the report trails the speed at the tick by
    ``wheel_filter_s`` once the start has died out ((7/8)^200 of it)."""
    y = 0.0
    for k in range(1, 201):
        y += (ACCEL * (k - 0.5) * TICK_S - y) / 2**SHIFT
    assert (ACCEL * 200 * TICK_S - y) / ACCEL == pytest.approx(SPEED_FILTER_DELAY_S, rel=1e-9)


def test_the_predicted_report_follows_the_board_through_a_speed_step(model):
    with_filter = reported_error(model, wheel_filter_s=SPEED_FILTER_DELAY_S)
    without = reported_error(model)
    # the approximation omega - tau_f omega_dot misses up to 0.08 rad/s where the ramp starts
    # and ends (the curvature term's, below)
    assert with_filter < 0.1, with_filter
    assert without > 0.5, without  # the report trails the wheel by 7.5 ms at 100 rad/s^2


def test_the_low_pass_miss_is_within_its_curvature_term(model):
    """Where the rate bends, the delay misses the low-pass's next term, tau_f^2 d^2 omega/dt^2,
    which the fusion adds to the noise: for a rate decaying with the lag (after a ramp's end)
    the whole remainder is that term / (1 - tau_f / lag), 1.18 times it here; at the bends
    themselves less, the low-pass not yet caught up with the change."""
    misses, curves = reported_misses(model, wheel_filter_s=SPEED_FILTER_DELAY_S)
    factor = 1.0 / (1.0 - SPEED_FILTER_DELAY_S / TAU_S)
    assert np.all(misses <= factor * curves + 1e-3), (misses / curves).max()
    assert misses.max() > 0.05  # a miss worth its term: seven telemetry sigmas


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
