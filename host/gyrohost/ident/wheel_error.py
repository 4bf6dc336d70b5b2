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

An error well under the reports' noise is lost in the spread of their variance: over one
log's 16 s of four wheels at 50 Hz its standard error is some 2.5 % of the noise's variance,
two of it (0.0033 rad/s)^2. Where the difference comes out below two standard errors, the
filter takes the error at that resolution: a loop whose error the logs cannot tell from none
(0.002 rad/s, say) leaves the filter somewhat cautious about its wheels; taken as nil, the
filter's wheel speeds would be sure to a tenth of what they are off by.
"""

import math
from typing import NamedTuple

import numpy as np

from gyrohost.estimator.config import MIN_WHEEL_WALK
from gyrohost.ident.forward import command_rows

SETTLE_LAGS = 5.0
"""Lags of the stretch's start left out, after the board's ramp (e^-5: under 1 % of a step)."""

RESOLUTION_ERRORS = 2.0
"""Standard errors of the variance below which an error counts as unresolved (one-sided: an
error the logs could not tell from none is under this 98 % of the time)."""


class SpeedError(NamedTuple):
    """The wheels' speed-error variance ``variance`` (rad^2/s^2, may be negative: the reports'
    less their noise's), the ``resolution`` of that difference (rad^2/s^2,
    :data:`RESOLUTION_ERRORS` of its standard errors) and the ``count`` of reports."""

    variance: float
    resolution: float
    count: int


def speed_error_variance(recs, est) -> SpeedError:
    """The wheels' speed error from the recordings ``recs`` (:class:`.forward.Recording`:
    reports and commands, scene wheel order) for the filter settings ``est`` (its wheel lag,
    ramp rate and report noise), pooled over wheels and recordings (count 0: none, NaN).

    The variance of a sample variance of ``N`` reports whose deviations correlate as an AR(1)
    of lag-one correlation ``rho`` is ``2 s^4 (1 + rho^2) / ((1 - rho^2) N)``: ``rho`` is
    measured on the same deviations, the noise's share and the error's together."""
    centred = [e - e.mean(axis=0) for rec in recs if (e := _longest_settled(rec, est)) is not None]
    count = sum(d.size - d.shape[1] for d in centred)
    if count == 0:
        return SpeedError(math.nan, math.nan, 0)
    squares = sum(float(np.sum(d * d)) for d in centred)
    rho = sum(float(np.sum(d[1:] * d[:-1])) for d in centred) / squares
    spread = squares / count
    se = spread * math.sqrt(2.0 * (1.0 + rho**2) / ((1.0 - rho**2) * count))
    return SpeedError(spread - est.wheel_speed_std_rad_s**2, RESOLUTION_ERRORS * se, count)


def _longest_settled(rec, est):
    """The reports less the command (k, n_w) over the longest stretch of one command, from when
    the board's ramp to it (at ``est``'s ramp rate) and :data:`SETTLE_LAGS` of its wheel lags
    are over; None without two."""
    if not len(rec.t_command_s) or len(rec.t_wheels_s) < 2:
        return None
    t = rec.t_wheels_s
    i = command_rows(rec, t)
    first, step = _changes(rec.command_rad_s)
    since = rec.t_command_s[first][i]
    settled = t - since >= step[first][i] / est.wheel_accel_rad_s2 + SETTLE_LAGS * est.wheel_lag_s
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


class WheelWalk(NamedTuple):
    """The filter's wheel walk ``psd`` (rad^2/s^3), the speed error's ``sigma`` (rad/s) it
    stands for, and whether the logs ``resolved`` it (else ``sigma`` is their resolution)."""

    psd: float
    sigma: float
    resolved: bool


def wheel_walk(recs, est) -> WheelWalk | None:
    """The filter's wheel walk ``2 sigma^2 / lag`` (at least the filter's
    :data:`~gyrohost.estimator.config.MIN_WHEEL_WALK`) from the logs' settled reports, with
    ``sigma^2`` the measured variance or, below it, its resolution; None where they have no
    reports or the filter models no wheel lag."""
    error = speed_error_variance(recs, est)
    if error.count == 0 or not est.wheel_lag_s > 0.0:
        return None
    resolved = error.variance >= error.resolution
    sigma = math.sqrt(error.variance if resolved else error.resolution)
    return WheelWalk(max(2.0 * sigma**2 / est.wheel_lag_s, MIN_WHEEL_WALK), sigma, resolved)


def describe(walk: WheelWalk) -> str:
    """The speed error as ``gyrotens identify`` prints it and the overlay notes it."""
    if walk.resolved:
        return f"std {walk.sigma:.4f} rad/s"
    return f"std below the logs' resolution, taken as {walk.sigma:.4f} rad/s"
