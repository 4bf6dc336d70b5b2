"""The wheels' speed-loop error measured from a log (ident/wheel_error.py), on reports made as
the simulated board makes them: the command, an error wandering over the loop's lag, the
report's own noise.

The estimate is the reports' variance less the noise's (0.0146^2), so its spread is the
noise's sample variance's, ``0.0146^2 sqrt(2 / N)``: over one identification log's 16 s of
four wheels (N = 3,150) that is 5.4e-6 rad^2/s^2, a fifth of 0.005 rad/s squared. The checks
hold a log ten times as long (160 s), the spread then 1.7e-6: 0.005 rad/s measured within 20 %
(1.1e-5 rad^2/s^2) is six of it, 0.015 within 20 % far more."""

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
    walk = wheel_error.wheel_walk([recording(sigma)], EST)
    assert walk.resolved
    assert walk.sigma == pytest.approx(sigma, rel=0.2)
    assert walk.psd == pytest.approx(2 * walk.sigma**2 / EST.wheel_lag_s)


def test_a_loop_without_error_is_taken_at_the_logs_resolution():
    """Over 160 s the resolution is two spreads (1.7e-6 each) of the variance, about 0.0018
    rad/s (the reports' deviations nearly white here): a loop without error reads below it,
    unresolved, and the filter takes that, not nil, nor the report noise (0.0146)."""
    error = wheel_error.speed_error_variance([recording(0.0)], EST)
    assert error.resolution == pytest.approx(2 * 0.0146**2 * np.sqrt(2 / error.count), rel=0.1)
    walk = wheel_error.wheel_walk([recording(0.0)], EST)
    assert not walk.resolved
    assert walk.sigma == pytest.approx(np.sqrt(error.resolution))
    assert walk.psd == pytest.approx(max(2 * walk.sigma**2 / EST.wheel_lag_s, MIN_WHEEL_WALK))


def test_one_log_never_takes_an_error_it_barely_sees_as_less():
    """Over one identification log's 16 s an error of 0.002 rad/s (4e-6 rad^2/s^2) is near
    one spread of the variance (5.4e-6): resolved or not, the filter takes at least it (the
    resolution, about 0.0033 rad/s, where unresolved) and not the report noise (0.0146)."""
    walk = wheel_error.wheel_walk([recording(0.002, step_at_s=16.0)], EST)
    assert 0.002 < walk.sigma < 0.006


def test_without_commands_nothing_is_measured():
    rec = recording(0.01)
    rec.t_command_s, rec.command_rad_s = np.zeros(0), np.zeros((0, 4))
    assert wheel_error.wheel_walk([rec], EST) is None


def test_the_overlay_carries_the_measured_walk():
    result = SimpleNamespace(params=[])
    text = overlay_toml_of(result, wheel_error.WheelWalk(0.0123, 0.0177, True))
    assert "wheel_accel_psd_rad2_s3 = 0.0123  # the wheels' speed error" in text
    assert "std 0.0177 rad/s" in text
    text = overlay_toml_of(result, wheel_error.WheelWalk(0.0004, 0.0033, False))
    assert "std below the logs' resolution, taken as 0.0033 rad/s" in text


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
