"""Why a bring-up step (ports, servo set-up) was refused or failed.

Each subclasses :class:`gyrohost.errors.GyrohostError` and ``ValueError`` (bad input, refused
before anything moved) or ``RuntimeError`` (a failure while running)."""

from gyrohost.errors import GyrohostError


class ServoSetupError(GyrohostError, RuntimeError):
    """The set-up cannot go on (no servo, several, no confirmation)."""


class PortAccessError(GyrohostError, ValueError):
    """One or more configured ports cannot be opened; one line per port in the message."""
