"""The simulated rig's ptys for the bring-up commands."""

import pytest
from bringup_rig import served_rig

from gyrohost.config import load_rig_config
from gyrohost.resources import shipped


@pytest.fixture(scope="module")
def rig_ports():
    """Device name -> pty path of one simulated rig (sim-rig), shared by a module's tests."""
    with served_rig(load_rig_config(shipped("config", "sim-rig"))) as ports:
        yield ports
