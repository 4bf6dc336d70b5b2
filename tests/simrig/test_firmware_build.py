"""Where the simavr wheel board's binaries come from: configuration keys, --firmware-build or
GYROTENS_FIRMWARE_BUILD, else an error saying what to set (no firmware build needed here)."""

import pytest

from gyrohost.cli import main
from gyrohost.commands.rig import with_firmware_build
from gyrohost.config import load_rig_config
from gyrohost.resources import shipped
from gyrohost.simrig import simavr
from gyrohost.simrig.config import sim_config


def fake_build(root):
    (root / "avr").mkdir(parents=True)
    (root / "sim").mkdir()
    (root / "avr" / "wheelboard.elf").write_bytes(b"")
    (root / "sim" / "fil_harness").write_bytes(b"")
    return root


def test_without_any_setting_the_error_says_what_to_set_and_how_to_build(monkeypatch):
    monkeypatch.delenv(simavr.FIRMWARE_BUILD_ENV, raising=False)
    with pytest.raises(simavr.HarnessError) as info:
        simavr.firmware_elf()
    message = str(info.value)
    for needed in ("GYROTENS_FIRMWARE_BUILD", "--firmware-build", "simavr_elf", "make -C firmware"):
        assert needed in message


def test_the_environment_variable_names_the_build(tmp_path, monkeypatch):
    build = fake_build(tmp_path / "build")
    monkeypatch.setenv(simavr.FIRMWARE_BUILD_ENV, str(build))
    assert simavr.firmware_elf() == build / "avr" / "wheelboard.elf"
    assert simavr.harness_binary() == build / "sim" / "fil_harness"


def test_firmware_build_option_sets_the_configuration_keys(tmp_path):
    build = fake_build(tmp_path / "build")
    config = with_firmware_build(load_rig_config(shipped("config", "sim-rig")), build)
    assert sim_config(config).wheels.simavr_elf == str(build / "avr" / "wheelboard.elf")
    assert sim_config(config).wheels.simavr_harness == str(build / "sim" / "fil_harness")


def test_gyrotens_rig_names_a_missing_build(tmp_path, capsys):
    argv = ["rig", "--wheel-board", "simavr", "--firmware-build", str(tmp_path), "--duration", "1"]
    assert main(argv) == 2
    assert f"firmware ELF in {tmp_path / 'avr'}, found none" in capsys.readouterr().err
