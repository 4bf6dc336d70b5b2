"""Host controller for the gyroscopic tensegrity rig: drivers, estimator, schedule, rig."""

from gyrotensegrity import __version__

__all__ = ["__version__"]
