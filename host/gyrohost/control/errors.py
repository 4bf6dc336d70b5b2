"""Exception types of the schedule and control package (they subclass ``ValueError``)."""

from gyrohost.errors import GyrohostError


class ScheduleError(GyrohostError, ValueError):
    """A schedule file or schedule value is invalid; the message names the file and key."""


class PlanError(GyrohostError, ValueError):
    """A planning request is invalid (target, duration, limits or model not supported)."""


class PastDeadline(GyrohostError, RuntimeError):
    """A bounded computation stopped: its next piece of work would end past its deadline
    (:class:`.deadline.Deadline`)."""
