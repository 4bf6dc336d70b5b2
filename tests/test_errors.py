"""Every exception class of ``gyrohost`` subclasses the one base, ``GyrohostError``.

Each also subclasses ``ValueError`` (bad input) or ``RuntimeError`` (a failure while running),
so a caller catches all of the package's errors with one clause and still tells the kinds apart.
"""

import importlib
import inspect
import pkgutil

import gyrohost
from gyrohost.errors import GyrohostError


def defined_exceptions():
    """(module name, class) of every exception class defined in a ``gyrohost`` module."""
    for info in pkgutil.walk_packages(gyrohost.__path__, "gyrohost."):
        if info.name.endswith("__main__"):
            continue  # importing it runs the command line
        module = importlib.import_module(info.name)
        for obj in vars(module).values():
            if (
                inspect.isclass(obj)
                and issubclass(obj, BaseException)
                and obj.__module__ == module.__name__
            ):
                yield module.__name__, obj


def test_walk_finds_the_package_errors():
    found = {cls.__name__ for _, cls in defined_exceptions()}
    assert {"ConfigError", "CliError", "ServoFaultError", "EstimatorError"} <= found


def test_every_exception_subclasses_gyrohost_error():
    stray = [
        f"{module}.{cls.__name__}"
        for module, cls in defined_exceptions()
        if cls is not GyrohostError and not issubclass(cls, GyrohostError)
    ]
    assert not stray, f"exceptions outside GyrohostError: {stray}"


def test_every_exception_says_its_kind():
    vague = [
        f"{module}.{cls.__name__}"
        for module, cls in defined_exceptions()
        if cls is not GyrohostError and not issubclass(cls, (ValueError, RuntimeError))
    ]
    assert not vague, f"neither ValueError nor RuntimeError: {vague}"
