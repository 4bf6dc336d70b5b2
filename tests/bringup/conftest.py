"""The simulated rig's ptys for the bring-up commands."""

import threading

import pytest

from gyrohost.config import load_rig_config
from gyrohost.resources import shipped
from gyrohost.simrig.process import RigProcess


@pytest.fixture(scope="module")
def rig_ports():
    """Device name -> pty path of one simulated rig (sim-rig), shared by a module's tests."""
    with RigProcess(load_rig_config(shipped("config", "sim-rig"))) as rig:
        done = threading.Event()
        drain = threading.Thread(target=_drain_truth, args=(rig, done), daemon=True)
        drain.start()
        yield dict(rig.paths)
        done.set()
        drain.join()


def _drain_truth(rig, done: threading.Event) -> None:
    """Read the truth the rig sends (the tests want none), so its pipe never fills up."""
    while not done.wait(0.05):
        rig.truth()
