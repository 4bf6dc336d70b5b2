"""Fixtures shared by every test folder."""

import os
import signal
import subprocess
from pathlib import Path

import pytest

FIRMWARE_BUILD = Path(__file__).resolve().parents[1] / "firmware" / "build"

# The FIL tests and the simulated rig's simavr wheel board run this checkout's firmware build
# (``make -C firmware check``); subprocesses of the tests inherit the setting.
os.environ["GYROTENS_FIRMWARE_BUILD"] = str(FIRMWARE_BUILD)


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


@pytest.fixture(autouse=True)
def private_runtime_dir(tmp_path_factory, monkeypatch):
    """A runtime directory of each test's own: ``gyrotens rig`` writes its default ports file and
    control socket there, so rigs of tests running side by side never meet."""
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path_factory.mktemp("xdg")))
