"""Rig configuration loader: shipped files, every kind of error, documentation coverage."""

import typing
from dataclasses import fields, is_dataclass
from pathlib import Path

import pytest

from gyrohost.config import (
    EMULATED_PORT,
    ConfigError,
    ImuConfig,
    RigConfig,
    ServoBusConfig,
    ServoConfig,
    StartCheckConfig,
    WheelboardConfig,
    load_rig_config,
    rig_config_from_dict,
)
from gyrohost.drivers.servos import StringServoBus
from gyrohost.resources import shipped
from gyrohost.simrig.config import (
    ImuEmuConfig,
    ServoEmuConfig,
    StreamFaultConfig,
    truth_scene_path,
    with_truth_scene,
)

ROOT = Path(__file__).resolve().parents[2]
SERVO = {"name": "s13", "id": 1, "pulley_radius_m": 0.01, "length_at_zero_m": 0.3}


def test_simulated_rig_file():
    cfg = load_rig_config(shipped("config", "sim-rig"))
    assert cfg.imu.port == cfg.servos.port == cfg.wheelboard.port == EMULATED_PORT
    assert [s.name for s in cfg.servos.servo] == ["s13", "s24"]
    assert cfg.wheelboard.baud == 1_000_000
    assert cfg.scene == "dbar-gyro" and cfg.scene_path == shipped("scene", "dbar-gyro")
    StringServoBus(cfg.servos)  # limits map into the multi-turn range


def test_lab_rig_template():
    cfg = load_rig_config(shipped("config", "lab-rig"))
    assert cfg.servos.port == "/dev/gyrotens-servos" and cfg.imu.port == "/dev/rfcomm0"
    assert cfg.wheelboard.port == "/dev/gyrotens-wheels"  # the names of tools/udev
    assert cfg.sim == {}  # a real rig has no simulated devices
    assert cfg.run == RigConfig().run  # today's limits, written out
    StringServoBus(cfg.servos)


def test_run_table_sets_the_run_limits_and_names_a_bad_key(tmp_path):
    from gyrohost.run.settings import RunSettings

    path = tmp_path / "rig.toml"
    path.write_text("[run]\nmax_tilt_rad = 0.6\nimu_silence_s = 0.25\n")
    settings = RunSettings.for_rig(load_rig_config(path))
    assert settings.max_tilt_rad == 0.6 and settings.imu_silence_s == 0.25
    assert settings.wheel_silence_s == RunSettings().wheel_silence_s == 0.5
    path.write_text("[run]\nimu_silence_s = 0.0\n")
    with pytest.raises(ConfigError, match="key 'run.imu_silence_s' is 0.0, below the minimum"):
        load_rig_config(path)
    path.write_text("[run]\nmax_tilt_rad = 0.05\n")
    with pytest.raises(ConfigError, match="key 'run.max_tilt_rad': 0.05 rad must exceed start_c"):
        load_rig_config(path)
    path.write_text("[run]\nsteady_tolerance_rad_s = 20.0\n")
    with pytest.raises(ConfigError, match="'run.steady_tolerance_rad_s': must be smaller than"):
        load_rig_config(path)


def test_empty_file_gives_the_defaults(tmp_path):
    path = tmp_path / "empty.toml"
    path.write_text("")
    cfg = load_rig_config(path)
    assert cfg.imu == ImuConfig() and cfg.servos == ServoBusConfig()
    assert cfg.start_check == StartCheckConfig()
    assert cfg.source == str(path)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"imu": {"bogus": 1}}, "unknown key 'imu.bogus'"),
        ({"sim": {"servos": {"faults": {"stall": 1}}}}, "unknown key 'sim.servos.faults.stall'"),
        ({"source": "x"}, "unknown key 'source'"),  # set by the loader only
        ({"imu": {"baud": 4800}}, "key 'imu.baud' is 4800, must be one of"),
        ({"imu": {"timeout_s": "fast"}}, "key 'imu.timeout_s' must be a number, got str"),
        ({"imu": {"rate_hz": 100.0}}, "key 'imu.rate_hz' must be an integer"),
        ({"imu": {"rate_hz": True}}, "key 'imu.rate_hz' must be an integer"),
        ({"imu": {"mounting_rpy_rad": [0, 0]}}, "must have 3 elements, got 2"),
        ({"imu": {"mounting_rpy_rad": [0, 0, 4]}}, r"mounting_rpy_rad' is 4.0, above the max"),
        ({"imu": {"timeout_s": float("nan")}}, "must be finite"),
        ({"imu": 3}, "key 'imu' must be a table"),
        ({"servos": {"servo": [{**SERVO, "id": 300}]}}, r"'servos.servo\[0\].id' is 300, above"),
        ({"servos": {"servo": [{"name": "a", "id": 1}]}}, r"missing required key 'servos.servo"),
        ({"servos": {"servo": [SERVO, SERVO]}}, "duplicate servo IDs"),
        (
            {"servos": {"servo": [{**SERVO, "min_length_m": 0.5, "max_length_m": 0.4}]}},
            r"servos.servo\[0\].min_length_m': must be smaller",
        ),
        (
            {"sim": {"imu": {"faults": {"stall_period_s": 1.0, "stall_duration_s": 1.0}}}},
            "sim.imu.faults.stall_duration_s': must be shorter",
        ),
        ({"sim": {"servos": {"overload_ids": [1, 999]}}}, "overload_ids' is 999, above"),
        ({"start_check": {"angle_rad": 0.1}}, "unknown key 'start_check.angle_rad'"),
        ({"start_check": {"length_m": -0.001}}, "'start_check.length_m' is -0.001, below"),
        ({"start_check": {"attitude_rad": 4.0}}, "'start_check.attitude_rad' is 4.0, above"),
        ({"start_check": {"rate_rad_s": "1"}}, "'start_check.rate_rad_s' must be a number"),
        ({"sim": {"truth": {"scene": "nowhere"}}}, "key 'sim.truth.scene': nowhere"),
        ({"sim": {"truth": {"imu_rotation_deg": [0, 200, 0]}}}, "imu_rotation_deg' is 200.0"),
        (
            {"servos": {"servo": [SERVO]}, "sim": {"truth": {"servo_zero_offset_rad": [0, 0]}}},
            r"sim.truth.servo_zero_offset_rad': has 2 values for 1 \[\[servos.servo\]\]",
        ),
    ],
)
def test_errors_name_the_file_and_key(data, message):
    with pytest.raises(ConfigError, match=message) as info:
        assert truth_scene_path(rig_config_from_dict(data, "my-rig.toml"))
    assert str(info.value).startswith("my-rig.toml: ")


def test_truth_scene_resolves_as_the_scene_does(tmp_path):
    path = tmp_path / "rig.toml"
    (tmp_path / "heavier.toml").write_text(shipped("scene", "dbar-gyro").read_text())
    path.write_text('scene = "dbar-gyro"\n[sim.truth]\nscene = "heavier.toml"\n')
    cfg = load_rig_config(path)
    assert truth_scene_path(cfg) == tmp_path / "heavier.toml"  # relative to the config
    assert cfg.scene_path == shipped("scene", "dbar-gyro")  # the host keeps its own
    path.write_text('[sim.truth]\nscene = "prism-gyro"\n')
    assert truth_scene_path(load_rig_config(path)) == shipped("scene", "prism-gyro")
    path.write_text("")
    assert truth_scene_path(load_rig_config(path)) == load_rig_config(path).scene_path
    flagged = with_truth_scene(load_rig_config(path), tmp_path / "heavier.toml")
    assert truth_scene_path(flagged) == tmp_path / "heavier.toml"


def test_unreadable_and_invalid_files(tmp_path):
    with pytest.raises(ConfigError, match="missing.toml: cannot read"):
        load_rig_config(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[imu\nport = 1")
    with pytest.raises(ConfigError, match="bad.toml: invalid TOML"):
        load_rig_config(bad)


def _keys(cls) -> list[str]:
    hints = typing.get_type_hints(cls)
    out = []
    for f in fields(cls):
        hint = hints[f.name]
        args = typing.get_args(hint)
        if not (is_dataclass(hint) or (args and is_dataclass(args[0]))):
            out.append(f.name)
    return out


@pytest.mark.parametrize(
    "cls",
    [ImuConfig, ServoBusConfig, ServoConfig, WheelboardConfig, ImuEmuConfig, ServoEmuConfig,
     StreamFaultConfig, StartCheckConfig],
)  # fmt: skip
def test_every_key_is_documented(cls):
    doc = (ROOT / "docs/rig-config.md").read_text()
    assert [k for k in _keys(cls) if f"`{k}`" not in doc] == []
