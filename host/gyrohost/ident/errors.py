"""Why an identification was refused or failed.

Each subclasses :class:`gyrohost.errors.GyrohostError` and ``ValueError`` (bad input, refused
before anything moved) or ``RuntimeError`` (a failure while running)."""

from gyrohost.errors import GyrohostError


class ParamsError(GyrohostError, ValueError):
    """An unknown or conflicting parameter group."""


class IdentDataError(GyrohostError, ValueError):
    """A recording cannot be fitted (a stream missing, too short, or a servo not in it)."""


class FitError(GyrohostError, RuntimeError):
    """The model could not run a recording under the nominal parameters."""


class FilterFitError(FitError):
    """The filter could not run a recording under the nominal parameters."""
