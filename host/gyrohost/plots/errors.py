"""Why a figure was refused.

Each subclasses :class:`gyrohost.errors.GyrohostError` and ``ValueError`` (bad input, refused
before anything was drawn)."""

from gyrohost.errors import GyrohostError


class PlotError(GyrohostError, ValueError):
    """A file too large to draw, or not one the figures can read; the message names it."""
