"""The wheels' speed-loop error, measured from identification logs: the filter's wheel walk.

The board holds each wheel near its commanded speed with an error that wanders over the loop's
lag (a first-order Gauss-Markov process of time constant ``wheel_lag_s``, docs/rig.md); the
filter carries it as the walk ``wheel_accel_psd_rad2_s3 = 2 sigma^2 / lag`` of the same
stationary spread ``sigma``. A shipped value is one rig's: a rig whose loop errs less makes the
filter too cautious about its wheels, one that errs more makes it overconfident
(reports/identification-heldout.md: the live NEES followed the held-out truths' error).

A report less its command, where the command has held, is that error plus the report's own
noise, whose spread the filter knows (``wheel_speed_std_rad_s``: a count through the firmware's
low-pass). So ``sigma^2`` is the reports' variance about their mean less that noise's. Only the
longest stretch of one command in each log counts (the identify schedule's 16 s of pulls at
its spin): after a step the loop's settling is still in the reports for a second or more,
twice the variance of the long stretch on the simulated rig.
"""

import math

import numpy as np

from gyrohost.estimator.config import MIN_WHEEL_WALK
from gyrohost.ident.forward import command_rows

SETTLE_LAGS = 5.0
"""Lags of the stretch's start left out, after the board's ramp (e^-5: under 1 % of a step)."""


def speed_error_variance(recs, est) -> tuple[float, int]:
    """The wheels' speed-error variance ``sigma^2`` (rad^2/s^2) from the recordings ``recs``
    (:class:`.forward.Recording`: reports and commands, scene wheel order) for the filter
    settings ``est`` (its wheel lag, ramp rate and report noise), pooled over wheels and
    recordings, and the reports it rests on (0: none, variance NaN)."""
    squares, count = 0.0, 0
    for rec in recs:
        e = _longest_settled(rec, est.wheel_lag_s, est.wheel_accel_rad_s2)
        if e is not None:
            squares += float(np.sum((e - e.mean(axis=0)) ** 2))
            count += e.size - e.shape[1]
    if count == 0:
        return math.nan, 0
    return squares / count - est.wheel_speed_std_rad_s**2, count


def _longest_settled(rec, lag_s: float, accel_rad_s2: float):
    """The reports less the command (k, n_w) over the longest stretch of one command, from when
    the board's ramp to it and :data:`SETTLE_LAGS` lags are over; None without two."""
    if not len(rec.t_command_s) or len(rec.t_wheels_s) < 2:
        return None
    t = rec.t_wheels_s
    i = command_rows(rec, t)
    first, step = _changes(rec.command_rad_s)
    since = rec.t_command_s[first][i]
    settled = t - since >= step[first][i] / accel_rad_s2 + SETTLE_LAGS * lag_s
    stretches = np.split(np.arange(len(t)), np.flatnonzero(np.diff(first[i]) != 0) + 1)
    keep = max((s[settled[s]] for s in stretches), key=len)
    return (rec.wheels_rad_s - rec.command_rad_s[i])[keep] if len(keep) >= 2 else None


def _changes(cmd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each command row, the row that first commanded its speeds; for each row, the
    largest change of a wheel's speed from the row before, rad/s (the first's: none)."""
    step = np.zeros(len(cmd))
    step[1:] = np.max(np.abs(np.diff(cmd, axis=0)), axis=1)
    first = np.maximum.accumulate(np.where(step > 0.0, np.arange(len(cmd)), 0))
    return first, step


def wheel_walk(recs, est) -> tuple[float, float] | None:
    """The filter's wheel walk ``2 sigma^2 / lag`` (rad^2/s^3, at least the filter's
    :data:`~gyrohost.estimator.config.MIN_WHEEL_WALK`) and ``sigma`` (rad/s) from the logs'
    settled reports; None where they have none or the filter models no wheel lag."""
    variance, count = speed_error_variance(recs, est)
    if count == 0 or not est.wheel_lag_s > 0.0:
        return None
    sigma = math.sqrt(max(variance, 0.0))
    return max(2.0 * sigma**2 / est.wheel_lag_s, MIN_WHEEL_WALK), sigma
