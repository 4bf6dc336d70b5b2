"""Fixtures shared by every test folder."""

import contextlib
import os
import signal
from pathlib import Path

import pytest

FIRMWARE_BUILD = Path(__file__).resolve().parents[1] / "firmware" / "build"

# The FIL tests and the simulated rig's simavr wheel board run this checkout's firmware build
# (``make -C firmware check``); subprocesses of the tests inherit the setting.
os.environ["GYROTENS_FIRMWARE_BUILD"] = str(FIRMWARE_BUILD)


# A shell starts background jobs with SIGINT ignored, and a process inherits that: Python then
# never raises KeyboardInterrupt, and a test that sends SIGINT to a child would wait on a child
# that ignores it. The test run takes Ctrl-C as a terminal user's process does, and so does
# every child it starts (a signal with a handler is back at its default after the child's exec).
signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(autouse=True)
def private_runtime_dir(tmp_path_factory, monkeypatch):
    """A runtime directory of each test's own: ``gyrotens rig`` writes its default ports file and
    control socket there, so rigs of tests running side by side never meet."""
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path_factory.mktemp("xdg")))


REAL_TIME = (
    "run/",
    "simrig/",
    "fil/",
    "bringup/",
    "host/test_config_overlay.py",
    "host/test_input_files.py",
    "estimator/test_estimator_sil.py",
    "ident/test_noise.py",
    "plots/test_log_figures.py",
    "test_wheel_install.py",
)
"""Test files and folders that run the simulated rig or the firmware in real time."""


def pytest_collection_modifyitems(config, items):
    """One real-time rig at a time: ``make test`` runs pytest on two workers (``--dist
    loadgroup``); the tests that run the simulated rig or the firmware against the wall clock go
    to one group, run one after the other on one worker, while the other worker takes the tests
    that only compute. Two rigs side by side on two cores (six processes: truth, run loop,
    estimator each) starved each other's deadlines. The other tests are grouped by module, so
    that a module's fixtures are built once, on one worker."""
    for item in items:
        group = "real-time" if is_real_time(item) else item.module.__name__
        item.add_marker(pytest.mark.xdist_group(group))


def is_real_time(item) -> bool:
    where = Path(item.fspath).relative_to(Path(__file__).parent).as_posix()
    return where.startswith(REAL_TIME)


COMPUTING_NICENESS = 10
"""The niceness of a worker while it runs a test that only computes: the scheduler then gives a
real-time rig (its truth, run loop and estimator) the CPU it needs when it needs it, and the
computing test the rest, as a lab laptop runs an experiment beside other work."""


def pytest_runtest_setup(item):
    """Real-time tests at normal priority, the others below it. Lowering a niceness again needs
    the privilege CI runs with (root); without it a worker that ran a computing test before its
    real-time ones keeps the lower priority, which only brings back the contention."""
    niceness = 0 if is_real_time(item) else COMPUTING_NICENESS
    with contextlib.suppress(PermissionError):
        os.setpriority(os.PRIO_PROCESS, 0, niceness)
