"""The wheels' speed-loop error measured from a log (ident/wheel_error.py), on reports made as
the simulated board makes them: the command, an error wandering over the loop's lag, the
report's own noise.

The estimate is the reports' variance less the noise's (0.0146^2), so its spread is the
noise's sample variance's, ``0.0146^2 sqrt(2 / N)``: over one identification log's 16 s of
four wheels (N = 3,200) that is 7.5e-6 rad^2/s^2, 15 % of 0.005 rad/s squared. The checks
hold a log ten times as long (160 s), the spread then 2.4e-6: 0.005 rad/s measured within
20 % is more than four of it, 0.015 within 20 % far more, and no error at all reads below
0.004 rad/s (1.6e-5 rad^2/s^2, near seven of it)."""

from types import SimpleNamespace

import numpy as np
import pytest

from gyrohost.estimator.config import MIN_WHEEL_WALK
from gyrohost.ident import wheel_error
from gyrohost.ident.report import overlay_toml

EST = SimpleNamespace(wheel_lag_s=0.05, wheel_accel_rad_s2=100.0, wheel_speed_std_rad_s=0.0146)
SPIN = 74.87


def recording(sigma: float, seed: int = 3, step_at_s: float = 160.0):
    """Reports every 20 ms of four wheels held at SPIN, stepped by 11 rad/s at ``step_at_s``;
    after the step the loop rings (an error 10 times larger) for the 4 s left of the log."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, step_at_s + 4.0, 0.02)
    rho = np.exp(-0.02 / EST.wheel_lag_s)
    error = np.zeros((len(t), 4))
    error[0] = rng.normal(0.0, sigma, 4)
    for k in range(1, len(t)):
        error[k] = rho * error[k - 1] + rng.normal(0.0, sigma * np.sqrt(1 - rho**2), 4)
    error[t >= step_at_s] *= 10.0
    t_cmd = np.arange(-0.01, t[-1] + 0.02, 0.01)
    cmd = np.where(t_cmd[:, None] < step_at_s, SPIN, SPIN + 11.0) * np.ones(4)
    reports = np.interp(t, t_cmd, cmd[:, 0])[:, None] + error
    reports += rng.normal(0.0, EST.wheel_speed_std_rad_s, reports.shape)
    return SimpleNamespace(t_wheels_s=t, wheels_rad_s=reports, t_command_s=t_cmd, command_rad_s=cmd)


@pytest.mark.parametrize("sigma", [0.005, 0.015])
def test_the_error_is_measured_without_the_reports_noise(sigma):
    walk, measured = wheel_error.wheel_walk([recording(sigma)], EST)
    assert measured == pytest.approx(sigma, rel=0.2)
    assert walk == pytest.approx(2 * measured**2 / EST.wheel_lag_s)


def test_a_loop_without_error_keeps_the_filters_floor():
    walk, measured = wheel_error.wheel_walk([recording(0.0)], EST)
    assert measured < 0.004  # the report noise alone (0.0146) left out
    assert walk == pytest.approx(max(2 * measured**2 / EST.wheel_lag_s, MIN_WHEEL_WALK))


def test_without_commands_nothing_is_measured():
    rec = recording(0.01)
    rec.t_command_s, rec.command_rad_s = np.zeros(0), np.zeros((0, 4))
    assert wheel_error.wheel_walk([rec], EST) is None


def test_the_overlay_carries_the_measured_walk():
    result = SimpleNamespace(params=[])
    text = overlay_toml_of(result, (0.0123, 0.0177))
    assert "wheel_accel_psd_rad2_s3 = 0.0123  # the wheels' speed error" in text
    assert "std 0.0177 rad/s" in text


def overlay_toml_of(result, walk):
    from unittest import mock

    from gyrohost.ident import report

    applied = SimpleNamespace(mounting_rpy_rad=(0.0, 0.0, 0.0))
    with (
        mock.patch.object(report, "apply_result", return_value=applied),
        mock.patch.object(report, "_determined_groups", return_value=set()),
        mock.patch.object(report, "mounting_covariance", return_value=None),
    ):
        return overlay_toml(result, SimpleNamespace(), None, walk)
