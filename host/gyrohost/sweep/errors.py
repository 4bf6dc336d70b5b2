"""Why a sweep specification was refused.

Each subclasses :class:`gyrohost.errors.GyrohostError` and ``ValueError`` (bad input, refused
before anything moved) or ``RuntimeError`` (a failure while running)."""

from gyrohost.errors import GyrohostError


class SpecError(GyrohostError, ValueError):
    """A sweep spec is unreadable or wrong; the message names the file and the key."""


class SweepSizeError(SpecError):
    """A sweep has more cases than allowed; nothing ran."""
