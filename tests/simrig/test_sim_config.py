"""The simulated rig's ``[sim]`` tables: apart from the real rig's configuration, checked when
the simulated rig reads them, and the shipped simulated rigs' EKF figures derived from them."""

import pytest

from gyrohost.config import ConfigError, load_rig_config
from gyrohost.estimator.config import EstimatorConfig, for_rig
from gyrohost.resources import shipped
from gyrohost.sil.emulator_keys import emulator_keys
from gyrohost.simrig.config import SimConfig, sim_config, with_sim_keys


@pytest.mark.parametrize("name", ["sim-rig", "prism-sim-rig"])
def test_a_shipped_simulated_rig_s_ekf_figures_are_its_emulators(name):
    """Each key its ``[estimator]`` table writes out is what :func:`emulator_keys` derives from
    its ``[sim]`` tables, and every derived key that differs from the EKF's default is written:
    a changed emulator or derivation shows here, not as a drifting NEES."""
    config = load_rig_config(shipped("config", name))
    default = EstimatorConfig()
    wanted = emulator_keys(config)
    used = for_rig(config)
    for key, value in wanted.items():
        value = tuple(value) if isinstance(value, list) else value
        if key in config.estimator or value != getattr(default, key):
            assert getattr(used, key) == value, key  # TOML floats read back to the bit


def test_a_real_rig_has_no_simulated_devices_and_gets_their_defaults():
    lab = load_rig_config(shipped("config", "lab-rig"))
    assert lab.sim == {}
    assert sim_config(lab) == SimConfig()


@pytest.mark.parametrize(
    ("table", "keys", "message"),
    [
        ("imu", {"gyro_noise": 1.0}, r"unknown key 'sim\.imu\.gyro_noise'"),
        ("wheels", {"kind": "real"}, r"'sim\.wheels\.kind' is 'real', must be one of"),
        ("truth", {"dt_s": 1.0}, r"'sim\.truth\.dt_s' is 1\.0, above the maximum"),
        ("truth", {"servo_zero_offset_rad": [0.1]}, r"has 1 values for 2 \[\[servos\.servo\]\]"),
    ],
)
def test_a_bad_sim_key_names_the_file_and_the_key(table, keys, message):
    config = with_sim_keys(load_rig_config(shipped("config", "sim-rig")), table, **keys)
    with pytest.raises(ConfigError, match=message) as info:
        sim_config(config)
    assert str(info.value).startswith(str(shipped("config", "sim-rig")))


def test_a_bad_sim_key_stops_a_simulated_run_before_anything_starts(tmp_path, capsys):
    from gyrohost.cli import main

    path = tmp_path / "rig.toml"
    path.write_text(shipped("config", "sim-rig").read_text() + "\n[sim.truth]\ndt_s = -1.0\n")
    assert main(["run", "--config", str(path), "--sim", "-o", str(tmp_path / "log")]) == 2
    assert "key 'sim.truth.dt_s' is -1.0, below the minimum" in capsys.readouterr().err
    assert not (tmp_path / "log").exists()
