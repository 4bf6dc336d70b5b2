"""``identify`` and ``noise`` read a log with the configuration it ran with (``rig_config`` of
its ``meta.json``); a different ``--config`` is used with a warning naming both."""

import json
from dataclasses import asdict, replace

import pytest

from gyrohost.config import ConfigError, load_rig_config
from gyrohost.ident.log_config import config_for_logs
from gyrohost.resources import shipped
from gyrohost.run.log import FORMAT


def log_of(folder, config):
    folder.mkdir()
    meta = {"format": FORMAT, "streams": {}, "rig_config": asdict(config)}
    (folder / "meta.json").write_text(json.dumps(meta))
    return folder


def test_the_logs_configuration_is_the_default_and_another_warns(tmp_path):
    sim = load_rig_config(shipped("config", "sim-rig"))
    lab = replace(sim, imu=replace(sim.imu, port="/dev/rfcomm0"), source="/lab/rig.toml")
    log = log_of(tmp_path / "run01", lab)
    config, warnings = config_for_logs([log], None)
    assert config.source == "/lab/rig.toml" and config.imu.port == "/dev/rfcomm0"
    assert warnings == []
    config, warnings = config_for_logs([log], "sim-rig")
    assert config.imu.port == sim.imu.port
    assert warnings == [f"{log} ran with the configuration /lab/rig.toml, read here with "
                        f"{sim.source}"]  # fmt: skip
    same, warnings = config_for_logs([log_of(tmp_path / "run02", sim)], "sim-rig")
    assert warnings == []  # the same keys and values: no warning


def test_a_folder_without_a_log_asks_for_the_configuration(tmp_path):
    with pytest.raises(ConfigError, match="no meta.json.*give the configuration with --config"):
        config_for_logs([tmp_path], None)
