"""The one base of the package's exceptions.

Every error ``gyrohost`` raises on purpose subclasses :class:`GyrohostError`, and also
``ValueError`` (bad input: a file, key, value or schedule) or ``RuntimeError`` (something failed
while running: a device, the rig, the estimator), so a caller catches all of them with one
``except GyrohostError`` and still tells the two kinds apart. Time stamps on errors are ``t_s``.
"""


class GyrohostError(Exception):
    """Base of every exception the ``gyrohost`` package raises on purpose."""


class ConfigError(GyrohostError, ValueError):
    """A rig configuration file or value is invalid; the message names the file and key."""
