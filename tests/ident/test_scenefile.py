"""The identified scene is written back whole: every shipped scene survives the round trip."""

import pytest

from gyrohost.ident.scenefile import scene_toml
from gyrohost.resources import shipped
from gyrotensegrity import load_scene

SCENES = [
    "dbar-gyro",
    "dbar-nospin",
    "dbar-rig",
    "double-pendulum",
    "prism-gyro",
    "prism-string-mass",
]


@pytest.mark.parametrize("name", SCENES)
def test_round_trip_of_every_shipped_scene(tmp_path, name):
    scene = load_scene(shipped("scene", name))
    path = tmp_path / f"{name}.toml"
    path.write_text(scene_toml(scene, "a header\nof two lines"))
    again = load_scene(path).to_dict()
    original = scene.to_dict()
    again.pop("source"), original.pop("source")
    assert again == original
