"""Why a benchmark case stopped.

Each subclasses :class:`gyrohost.errors.GyrohostError` and ``ValueError`` (bad input, refused
before anything moved) or ``RuntimeError`` (a failure while running)."""

from gyrohost.errors import GyrohostError


class RunStopped(GyrohostError, RuntimeError):
    """The bench stopped an integration early; the message says why.

    Raised over the wall-time budget, on a non-finite state or on a failed solver step.
    """
