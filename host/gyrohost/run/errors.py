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


class StartStateRefused(GyrohostError, ValueError):
    """The rig is not in the scene's initial state (nothing moved); the message says what
    differs and by how much."""


class LogError(GyrohostError, ValueError):
    """A log folder or row that does not follow the format; the message names the file and row."""


class LogWriteError(GyrohostError, RuntimeError):
    """Writing the log failed (a full disk, a lost drive); the message says where the log ends."""


class LiveUnavailable(GyrohostError, ValueError):
    """The live view cannot start: the ``foxglove-sdk`` package is missing, or the port is
    taken."""


class EstimatorProcessError(RunError):
    """The estimator's child process failed to start, fell too far behind or its pipe broke."""


class DeviceFault(GyrohostError, RuntimeError):
    """A device failed during a run; ``device`` names it (``imu``, ``wheels``, ``servos``)."""

    def __init__(self, device: str, message: str):
        super().__init__(f"{device}: {message}")
        self.device = device
