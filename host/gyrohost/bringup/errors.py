"""Why a bring-up step (ports, servo set-up) was refused or failed.

Each subclasses :class:`gyrohost.errors.GyrohostError` and ``ValueError`` (bad input, refused
before anything moved) or ``RuntimeError`` (a failure while running)."""

from gyrohost.errors import GyrohostError


class ServoSetupError(GyrohostError, RuntimeError):
    """The set-up cannot go on (no servo, several, no confirmation)."""


class PortAccessError(GyrohostError, ValueError):
    """One or more configured ports cannot be opened; one line per port in the message."""


class WheelSetupError(GyrohostError, RuntimeError):
    """A wheel-board step (offset check, spin) cannot go on or did not end as it should."""


class SetupInputError(GyrohostError, ValueError):
    """A bring-up command was given something it refuses before anything moves (a spin too
    fast, a jog past a string's limits, no port to open)."""
