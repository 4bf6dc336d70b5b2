"""Piecewise-linear schedules of time, held constant before the first and after the last point."""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Schedule:
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


def constant(value: float) -> Schedule:
    """A schedule that holds ``value`` at every time."""
    return Schedule(np.array([0.0]), np.array([float(value)]))
