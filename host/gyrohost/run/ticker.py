"""The host clock of a run, its fixed grid of ticks, and what a tick shows on the progress line.

The run's time ``t_s`` is ``time.monotonic`` since the run's time zero. Ticks are due on a fixed
grid of the host period; a tick that starts late skips the grid points it missed (the loop
catches up instead of spiralling), and every tick's period and lateness is recorded
(:class:`LoopTimer`) for the ``loop`` stream and the summary.
"""

import math
import time
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Readout:
    """The state of a run at one tick, for the progress line.

    Attributes
    ----------
    tilt_rad : float, rad
        The estimated tilt of the scene's attitude measure (NaN: none, or no estimate yet).
    omega_rad_s : tuple of float or None, rad/s
        The wheel speeds of the latest telemetry (None before the first).
    estimator : str
        ``off`` before the estimator starts, ``ok``, or its status bits by name
        (``WHEELS_TIMEOUT|IMU_RATE_REJECTED``).
    rpy_rad : tuple of 3 float or None, rad
        The estimated roll, pitch, yaw of the scene's body frame (None: no ``[attitude]``, or no
        estimate yet).
    """

    tilt_rad: float
    omega_rad_s: tuple | None
    estimator: str
    rpy_rad: tuple | None = None


def status_words(status) -> str:
    """An estimator status (``estimator.Status`` flags) in words: ``ok`` or the set bits' names
    joined by ``|``."""
    names = [flag.name for flag in type(status) if flag & status]
    return "|".join(names) if names else "ok"


@dataclass
class LoopTimer:
    """Periods and lateness of the fixed-rate loop's ticks.

    Parameters
    ----------
    period_s : float, s
        The nominal period.
    """

    period_s: float
    starts: list = field(default_factory=list)
    lates: list = field(default_factory=list)

    def record(self, start_s: float, due_s: float) -> None:
        """A tick started at ``start_s`` (host time, s) that was due at ``due_s``."""
        self.starts.append(start_s)
        self.lates.append(start_s - due_s)

    def stats(self) -> dict:
        """Period mean, std, p99 and max, lateness max and ticks more than a period late (s)."""
        periods = np.diff(self.starts)
        if periods.size == 0:
            return {"ticks": len(self.starts), "nominal_period_s": self.period_s}
        lates = np.array(self.lates)
        return {
            "ticks": len(self.starts),
            "nominal_period_s": self.period_s,
            "period_mean_s": float(periods.mean()),
            "period_std_s": float(periods.std()),
            "period_p99_s": float(np.percentile(periods, 99)),
            "period_max_s": float(periods.max()),
            "late_max_s": float(lates.max()),
            "late_p99_s": float(np.percentile(lates, 99)),
            "overruns": int(np.sum(lates > self.period_s)),
        }


def jitter_line(stats: dict) -> str:
    """One line of the loop timing figures (ms)."""
    if "period_mean_s" not in stats:
        return f"loop: {stats['ticks']} ticks (too few for timing figures)"

    def ms(key):
        return 1e3 * stats[key]

    rate = 1.0 / stats["nominal_period_s"]
    return (
        f"loop at {rate:g} Hz: {stats['ticks']} ticks, period mean {ms('period_mean_s'):.3f} ms, "
        f"std {ms('period_std_s'):.3f} ms, p99 {ms('period_p99_s'):.3f} ms, "
        f"max {ms('period_max_s'):.3f} ms; late max {ms('late_max_s'):.3f} ms, "
        f"{stats['overruns']} overruns"
    )


class Ticker:
    """The run's clock and tick grid.

    Parameters
    ----------
    rate_hz : float, Hz
        Ticks per second.

    Attributes
    ----------
    t0_ns : int
        ``time.monotonic_ns`` at the run's time zero (set by :meth:`start`), ns.
    timer : LoopTimer
    """

    def __init__(self, rate_hz: float):
        self.timer = LoopTimer(1.0 / rate_hz)
        self.t0_ns = 0
        self.next_due_s = 0.0

    def start(self) -> None:
        """Time zero of the run is now."""
        self.t0_ns = time.monotonic_ns()

    def now(self) -> float:
        """Host time since time zero, s."""
        return (time.monotonic_ns() - self.t0_ns) * 1e-9

    def regrid(self) -> None:
        """The next tick is due now, the grid runs on from here."""
        self.next_due_s = self.now()

    def catch_up(self) -> None:
        """Drop grid points already past (the next tick is due now at the latest)."""
        self.next_due_s = max(self.next_due_s, self.now())

    def wait(self) -> tuple[float, float]:
        """Sleep until the next tick is due; returns (start, due), host time, s."""
        period = self.timer.period_s
        due = self.next_due_s
        wait = due - self.now()
        if wait > 0:
            time.sleep(wait)
        start = self.now()
        self.timer.record(start, due)
        self.next_due_s = due + period * max(1, math.ceil((start - due) / period))
        return start, due
