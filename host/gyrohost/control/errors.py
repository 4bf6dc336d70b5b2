"""Exception types of the schedule and control package (they subclass ``ValueError``)."""


class ScheduleError(ValueError):
    """A schedule file or schedule value is invalid; the message names the file and key."""


class PlanError(ValueError):
    """A planning request is invalid (target, duration, limits or model not supported)."""
