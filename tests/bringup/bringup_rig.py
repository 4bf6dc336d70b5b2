"""The simulated rig for the bring-up tests, and rig configurations pointing at its ptys."""

import re
import threading
from contextlib import contextmanager

from gyrohost.resources import shipped
from gyrohost.simrig.process import RigProcess


@contextmanager
def served_rig(config):
    """A simulated rig on ``config`` in a process of its own; yields its device name -> pty
    path. The truth it sends is read and dropped (the tests want none), so its pipe never fills
    up."""
    with RigProcess(config) as rig:
        done = threading.Event()
        drain = threading.Thread(target=_drain_truth, args=(rig, done), daemon=True)
        drain.start()
        try:
            yield dict(rig.paths)
        finally:
            done.set()
            drain.join()


def _drain_truth(rig: RigProcess, done: threading.Event) -> None:
    while not done.wait(0.05):
        rig.truth()


def config_text(name: str, ports: dict[str, str], **replace: str) -> str:
    """The shipped configuration ``name`` with its three ports set to ``ports`` (device name ->
    path) and each ``old=new`` text of ``replace`` (keys: any label) swapped."""
    text = shipped("config", name).read_text()
    for table, device in (("imu", "imu"), ("servos", "servos"), ("wheelboard", "wheels")):
        text = re.sub(
            rf"(\[{table}\]\n(?:.*\n)*?port = )\"[^\"]*\"", rf'\1"{ports[device]}"', text, count=1
        )
    for old, new in replace.values():
        assert old in text, old
        text = text.replace(old, new)
    return text
