import pytest

from gyrohost.control import Planner
from gyrohost.resources import shipped_dir
from gyrotensegrity import Model, load_scene

SCENES = shipped_dir("scene")


@pytest.fixture(scope="session")
def dbar():
    return Model(load_scene(SCENES / "dbar-gyro.toml"))


@pytest.fixture(scope="session")
def planner(dbar):
    return Planner(dbar)
