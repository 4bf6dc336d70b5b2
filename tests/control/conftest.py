from pathlib import Path

import pytest

from gyrohost.control import Planner
from gyrotensegrity import Model, load_scene

SCENES = Path(__file__).resolve().parents[2] / "scenes"


@pytest.fixture(scope="session")
def dbar():
    return Model(load_scene(SCENES / "dbar-gyro.toml"))


@pytest.fixture(scope="session")
def planner(dbar):
    return Planner(dbar)
