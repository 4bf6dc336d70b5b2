"""Why a software-in-the-loop scoring was refused.

Each subclasses :class:`gyrohost.errors.GyrohostError` and ``ValueError`` (bad input, refused
before anything moved) or ``RuntimeError`` (a failure while running)."""

from gyrohost.errors import GyrohostError


class SilError(GyrohostError, ValueError):
    """A SIL run cannot start (its log folder exists) or stopped before its schedule ended."""
