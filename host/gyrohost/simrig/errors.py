"""Why the simulated rig failed or refused a setting.

Each subclasses :class:`gyrohost.errors.GyrohostError` and ``ValueError`` (bad input, refused
before anything moved) or ``RuntimeError`` (a failure while running)."""

from gyrohost.errors import GyrohostError


class RigSetupError(GyrohostError, ValueError):
    """The rig configuration does not fit the scene (unknown string or node, bad geometry)."""


class HarnessError(GyrohostError, RuntimeError):
    """The harness or the firmware ELF is missing, or the harness misbehaved."""


class RigError(GyrohostError, RuntimeError):
    """The rig failed at run time (its loop raised, or it was used the wrong way)."""


class FaultCommandError(GyrohostError, ValueError):
    """A fault request or command line that the rig does not understand."""


class PtyLinkError(GyrohostError, RuntimeError):
    """The pseudo-terminal pair could not be created or used."""


class RigProcessError(GyrohostError, RuntimeError):
    """The child process failed to start, its rig failed or the pipe to it broke."""


class PortsFileError(GyrohostError, ValueError):
    """A ports file that is missing or does not name the rig's ports; the message names the file
    and the key."""


class ControlError(GyrohostError, RuntimeError):
    """The rig's control socket cannot be reached or stopped answering."""
