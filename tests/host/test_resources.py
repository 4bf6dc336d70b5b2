"""Shipped scenes, configurations and schedules: a user's path wins, else a shipped name."""

import shutil

import pytest

from gyrohost.config import ConfigError, load_rig_config
from gyrohost.resources import ResourceError, resolve, shipped, shipped_names


def test_every_kind_ships_its_files():
    assert shipped_names("scene") == [
        "dbar-gyro", "dbar-nospin", "dbar-rig", "double-pendulum", "prism-gyro",
        "prism-rig", "prism-string-mass"
    ]  # fmt: skip
    assert shipped_names("config") == ["lab-rig", "prism-sim-rig", "sim-rig"]
    assert shipped_names("schedule") == ["identify", "paper", "prism-s7", "tilt-0.3rad-4s"]
    assert shipped("scene", "dbar-gyro.toml") == shipped("scene", "dbar-gyro")


def test_an_existing_path_wins_over_a_shipped_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert resolve("scene", "dbar-gyro") == shipped("scene", "dbar-gyro")
    (tmp_path / "dbar-gyro").write_text("# the user's own file\n")
    assert resolve("scene", "dbar-gyro") == tmp_path / "dbar-gyro"
    assert resolve("config", "sim-rig.toml", base=tmp_path) == shipped("config", "sim-rig")


def test_an_unknown_name_lists_the_shipped_ones(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ResourceError, match=r"dbar-gyr: no such file .*shipped: dbar-gyro, "):
        resolve("scene", "dbar-gyr")
    with pytest.raises(ResourceError, match=r"configs/sim-rig.toml: no such file"):
        resolve("config", "configs/sim-rig.toml")  # a path is never taken for a name


def test_a_copied_template_still_finds_its_scene(tmp_path):
    copy = tmp_path / "my-rig.toml"
    shutil.copy(shipped("config", "lab-rig"), copy)
    assert load_rig_config(copy).scene_path == shipped("scene", "dbar-gyro")


def test_a_scene_next_to_the_config_wins_and_a_bad_one_names_the_key(tmp_path):
    (tmp_path / "scenes").mkdir()
    own = tmp_path / "scenes" / "dbar-gyro.toml"
    shutil.copy(shipped("scene", "dbar-gyro"), own)
    (tmp_path / "rig.toml").write_text('scene = "scenes/dbar-gyro.toml"\n')
    assert load_rig_config(tmp_path / "rig.toml").scene_path == own
    (tmp_path / "bad.toml").write_text('scene = "no-such-scene"\n')
    config = load_rig_config(tmp_path / "bad.toml")
    with pytest.raises(ConfigError, match=r"bad.toml: key 'scene': no-such-scene: .*dbar-gyro"):
        _ = config.scene_path
