"""Host controller for the gyroscopic tensegrity rig: drivers, estimator, schedule, rig.

Importing the package imports nothing heavy (``gyrotens --help`` and ``--version`` stay quick);
``gyrohost.__version__`` is looked up on first use.
"""

__all__ = ["__version__", "version"]


def version() -> str:
    """The installed distribution's version; the source's ``gyrotensegrity.__version__`` when
    the package runs from a source tree that was never installed."""
    from importlib import metadata

    try:
        return metadata.version("gyrotensegrity")
    except metadata.PackageNotFoundError:
        from gyrotensegrity import __version__

        return __version__


def __getattr__(name: str) -> str:
    if name == "__version__":
        return version()
    raise AttributeError(f"module 'gyrohost' has no attribute {name!r}")
