"""Why a run stops or never starts.

Each subclasses :class:`gyrohost.errors.GyrohostError` and ``RuntimeError`` (the run could not
go on) or ``ValueError`` (the schedule was refused before anything moved).
"""

from gyrohost.errors import GyrohostError


class RunError(GyrohostError, RuntimeError):
    """The run could not go on (time-out, estimator fault); the message says why."""


class LimitBreach(RunError):
    """A measured or estimated value left its limit during the run."""


class ScheduleRefused(GyrohostError, ValueError):
    """The schedule breaks a servo limit or names a string no servo winds (nothing moved)."""


class RunRequestError(GyrohostError, ValueError):
    """A run asked for with options that do not go together or ports it cannot use."""
