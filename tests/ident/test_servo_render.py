"""The strings' rest lengths between the servos' reports, rendered by the commands."""

import numpy as np
import pytest

from gyrohost.estimator.servo_motion import lagged
from gyrohost.ident.servo_render import GRID_S, fit_response, rendered

DELAY_S, LAG_S = 0.012, 0.03
REPORT_PERIOD_S, TICK_S = 0.04, 0.01


def pulls(t_s):
    """Fast triangular pulls with rests, m: 0.12 m/s, 4 cm deep, twice (shape (k, 1))."""
    depth = np.interp(t_s, [0.0, 0.5, 0.83, 1.16, 1.6, 1.93, 2.26, 3.0], [0, 0, 1, 0, 0, 1, 0, 0])
    return (0.43 - 0.04 * depth)[:, None]


def servo(t_s, delay_s=DELAY_S, lag_s=LAG_S):
    """The servo's position at ``t_s`` under the 100 Hz commands, computed on a fine grid."""
    t_cmd = np.arange(0.0, 3.0, TICK_S)
    fine = np.arange(-0.2, 3.2, 1e-4)
    y = lagged(t_cmd, pulls(t_cmd), fine, lag_s)[:, 0]
    return np.interp(t_s - delay_s, fine, y)[:, None]


def test_lag_steps_exactly_as_the_closed_form():
    t = np.arange(0.0, 0.3, GRID_S)
    y = lagged(np.array([0.0, 0.05]), np.array([[0.0], [1.0]]), t, 0.02)[:, 0]
    after = t >= 0.05
    assert np.allclose(y[~after], 0.0)
    assert np.allclose(y[after], 1.0 - np.exp(-(t[after] - 0.05) / 0.02), atol=1e-12)


def test_the_response_is_found_from_25_hz_reports():
    t_cmd = np.arange(0.0, 3.0, TICK_S)
    t_rep = np.arange(0.003, 3.0, REPORT_PERIOD_S)
    rng = np.random.default_rng(1)
    reports = servo(t_rep) + rng.normal(0.0, 5e-6, (len(t_rep), 1))
    response = fit_response(t_rep, reports, t_cmd, pulls(t_cmd))
    assert response.delay_s == pytest.approx(DELAY_S, abs=1.5e-3)
    assert response.lag_s == pytest.approx(LAG_S, rel=0.1)
    assert response.rms_m < 1e-5


def test_rendered_follows_the_corners_that_straight_lines_cut():
    t_cmd = np.arange(0.0, 3.0, TICK_S)
    t_rep = np.arange(0.003, 3.0, REPORT_PERIOD_S)
    offset_m = 2e-4  # a level the commands do not carry: the reports' difference restores it
    reports = servo(t_rep) + offset_m
    t, lengths, _ = rendered(t_rep, reports, t_cmd, pulls(t_cmd))
    inside = (t > t_rep[0]) & (t < t_rep[-1])
    truth = servo(t[inside])[:, 0] + offset_m
    straight = np.interp(t[inside], t_rep, reports[:, 0]) - truth
    error = lengths[inside, 0] - truth
    assert np.max(np.abs(straight)) > 5e-4
    assert np.max(np.abs(error)) < 0.1 * np.max(np.abs(straight))


def test_a_log_s_reports_are_rendered_with_the_rig_s_servo_response(tmp_path):
    """An in-process recording (servos: a first-order 50 ms lag, read at 25 Hz): the response
    fitted to the reports is the rig's, and the rendered lengths are its commands through it."""
    from gyrohost.config import load_rig_config
    from gyrohost.estimator.config import servo_speed_m_s
    from gyrohost.ident.logs import load_recording
    from gyrohost.ident.simcheck import record_log, write_rigs
    from gyrohost.sil.emulator_keys import emulated_servo_lag_s

    nominal, truth = write_rigs(tmp_path, 2.5)
    log = record_log(truth, 1, tmp_path / "log")
    config = load_rig_config(nominal)
    lag_s, speed = emulated_servo_lag_s(config), servo_speed_m_s(config)
    reports = load_recording(log, config, 4)
    commands = load_recording(log, config, 4, commanded=True)
    assert commands.servo_response is None
    response = reports.servo_response
    assert abs(response.delay_s) < 1e-3
    assert response.lag_s == pytest.approx(lag_s, rel=0.02)
    t = np.arange(0.0, commands.t_imu_s[-1], 0.005)
    exact = lagged(commands.t_servos_s, commands.servos_m, t, lag_s, speed)
    read = [np.interp(t, reports.t_servos_s, v) for v in reports.servos_m.T]
    assert np.max(np.abs(np.column_stack(read) - exact)) < 2e-5  # m: the reads' 15 um steps
