"""Fixtures shared by every test folder."""

import signal
import subprocess

import pytest


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.fixture
def terminal_popen():
    """``subprocess.Popen`` for a child that takes Ctrl-C as a terminal user's process does.

    A shell starts background jobs with SIGINT ignored, and a child inherits that; Python then
    never raises KeyboardInterrupt. Tests that send SIGINT must not depend on how the test run
    itself was started, so the child gets the default SIGINT disposition back.
    """

    def popen(*args, **kwargs):
        return subprocess.Popen(*args, preexec_fn=_default_sigint, **kwargs)

    return popen
