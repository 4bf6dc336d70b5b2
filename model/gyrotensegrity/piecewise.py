"""Piecewise-linear functions of time (a scene's rest lengths, wheel speeds and torques), held
constant before the first and after the last point. Not to be confused with the host's experiment
schedule (:class:`gyrohost.control.schedule.Schedule`), which plays several strings and wheels."""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PiecewiseLinear:
    """A piecewise-linear function of time.

    Parameters
    ----------
    t : ndarray, shape (k,), s
        Strictly increasing sample times.
    value : ndarray, shape (k,)
        Values at the sample times (unit of the quantity scheduled).
    """

    t: np.ndarray
    value: np.ndarray

    def __call__(self, t: float) -> float:
        return float(np.interp(t, self.t, self.value))

    def to_dict(self) -> dict:
        return {"t": self.t.tolist(), "value": self.value.tolist()}


def constant(value: float) -> PiecewiseLinear:
    """A schedule that holds ``value`` at every time."""
    return PiecewiseLinear(np.array([0.0]), np.array([float(value)]))
