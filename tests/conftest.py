"""Fixtures shared by every test folder."""

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
)
"""Test files and folders that run the simulated rig or the firmware in real time."""


@pytest.hookimpl(tryfirst=True)
@pytest.fixture(scope="session")
def realtime_run(tmp_path_factory) -> Path:
    """A log folder of a real-time run of the simulated rig (the first of the estimator's
    recorded batch T): the devices' streams, the live estimate and the rig's truth, its scene
    the shipped dbar-gyro. Shared: read it, write elsewhere."""
    import json
    import tarfile

    from gyrohost.resources import shipped

    root = tmp_path_factory.mktemp("realtime-run")
    with tarfile.open(
        Path(__file__).parent / "estimator" / "data" / "realtime-run-T01.tar.xz"
    ) as tar:
        tar.extractall(root, members=[m for m in tar if m.name.startswith("run01")], filter="data")
    folder = root / "run01"
    meta = json.loads((folder / "meta.json").read_text())
    meta["scene"] = str(shipped("scene", "dbar-gyro"))
    (folder / "meta.json").write_text(json.dumps(meta))
    return folder


def pytest_collection_modifyitems(config, items):
    """The tests that run the simulated rig or the firmware against the wall clock are marked
    ``real_time`` (before ``-m`` selects): ``make test`` runs the others on two workers, a
    module to a worker (``--dist loadscope``: a module's fixtures are built once), then these:
    the simulated rig's one after the other, the firmware-in-the-loop ones (``tests/fil``) beside
    them. Beside a computing test, even one at a lower priority, a rig's estimator process fell
    more than a second behind its loop and the product's own fail-safe stopped the run: a rig
    run needs most of the machine, and the simavr harness, about 0.4 of a core, is all that
    fits beside it."""
    for item in items:
        if is_real_time(item):
            item.add_marker(pytest.mark.real_time)


def is_real_time(item) -> bool:
    where = Path(item.fspath).relative_to(Path(__file__).parent).as_posix()
    return where.startswith(REAL_TIME)
