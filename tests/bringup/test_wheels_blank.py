"""A wheel board with a blank EEPROM, the real firmware (simavr harness) and the emulator
(``[sim.wheels] blank_eeprom``): the first spin-up is refused naming ``gyrotens wheels
calibrate``, ``gyrotens doctor`` fails every wheel's offset with the line docs/bring-up.md shows,
and after the calibration of one wheel that wheel spins."""

import re
from pathlib import Path

import pytest
from bringup_rig import config_text, served_rig

from gyrohost.bringup.devices import wheel_board
from gyrohost.bringup.wheels import uncalibrated_wheels
from gyrohost.cli import main
from gyrohost.config import load_rig_config
from gyrohost.drivers import wheelproto as wp
from gyrohost.resources import shipped
from gyrohost.simrig import simavr
from gyrohost.simrig.config import WheelEmuConfig, with_sim_keys
from gyrohost.simrig.wheel_emu import WheelBoardEmulator

DOC = Path(__file__).resolve().parents[2] / "docs" / "bring-up.md"
NO = "/nonexistent/tty"


@pytest.fixture(params=[pytest.param("simavr", marks=pytest.mark.fil), "emulator"])
def blank_board(request):
    """The pty of a wheel board that has never been calibrated: the firmware's, or the
    simulated rig's emulator in a process of its own (as ``gyrotens rig`` serves it); yields
    (kind, port)."""
    if request.param == "simavr":
        elf, harness = simavr.build_binaries(simavr.firmware_build())
        with simavr.Harness(elf, harness=harness) as board_sim:
            yield request.param, board_sim.pty
    else:
        config = with_sim_keys(load_rig_config(shipped("config", "sim-rig")), "wheels",
                               blank_eeprom=True)  # fmt: skip
        with served_rig(config) as ports:
            yield request.param, ports["wheels"]


def test_a_blank_board_spins_once_its_wheel_is_calibrated(blank_board, tmp_path, capsys):
    kind, port = blank_board
    doc_line = next(
        line for line in DOC.read_text().splitlines() if line.startswith("FAIL  wheel offsets")
    )
    config = tmp_path / "rig.toml"
    config.write_text(config_text("sim-rig", {"imu": NO, "servos": NO, "wheels": port}))
    doctor = ["doctor", "--config", str(config), "--hello-timeout", "3"]
    spin = ["wheels", "spin", "--port", port, "--wheel", "0", "--speed", "10", "--time", "1"]
    assert main(spin) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("gyrotens wheels: error: SET_SPEEDS"), err
    assert "OFFSET_UNCALIBRATED" in err[0] and "gyrotens wheels calibrate --wheel 0" in err[0]
    assert main(doctor) == 1
    assert doc_line in capsys.readouterr().out.splitlines()
    assert main(["wheels", "calibrate", "--port", port, "--wheel", "0"]) == 0
    out = capsys.readouterr().out
    assert "wheel 0: ENC_OFFSET_M0 = " in out and "saved to EEPROM" in out, out
    with wheel_board(port) as board:
        assert uncalibrated_wheels(board) == [1, 2, 3]
    assert main(spin) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    measured = float(re.search(r"wheel 0: measured (\S+) rad/s", out).group(1))
    assert abs(measured - 10.0) < 1.0 and "wheel 0: stopped" in out, (kind, out)


def test_the_emulated_board_keeps_the_firmware_rules_of_a_blank_eeprom():
    """On the emulator's own clock (frames handed to it, a heartbeat every 10 ms): a blank board
    refuses a closed-loop setpoint for each wheel until that wheel is calibrated or its
    ENC_OFFSET set, and clearing PARAMS_DEFAULTED lifts nothing; after a PARAM_SAVE a reset
    boots from the saved image; PARAM_DEFAULTS makes every wheel uncalibrated again."""
    with WheelBoardEmulator(WheelEmuConfig(blank_eeprom=True)) as dev:
        host = _ClockedHost(dev)
        assert wp.fault_names(dev.fault_word) == ["PARAMS_DEFAULTED"]
        assert host.uncalibrated() == [0, 1, 2, 3]
        host.send("CALIBRATE_ENC", wheel=0)
        host.send("PARAM_SET", param_id=wp.PARAM_BY_NAME["ENC_OFFSET_M2"].id, value=1234)
        host.send("CLEAR_FAULTS", mask=0xFFFF)
        assert (dev.fault_word, host.uncalibrated()) == (0, [1, 3])
        host.send("PARAM_SAVE")
        host.idle(0.5)  # the save takes 0.3 s
        dev.reset()
        host.idle(0.05)
        assert dev.boots == 2 and "PARAMS_DEFAULTED" not in wp.fault_names(dev.fault_word)
        assert dev.params[wp.PARAM_BY_NAME["ENC_OFFSET_M2"].id] == 1234
        assert host.uncalibrated() == []
        host.send("PARAM_DEFAULTS")
        assert host.uncalibrated() == [0, 1, 2, 3]


class _ClockedHost:
    """Hands frames to an emulator on its own clock (no thread, no pty), 10 ms apart, with a
    heartbeat at each step; the emulator boots at 0 s."""

    def __init__(self, dev: WheelBoardEmulator):
        self.dev, self.t_s = dev, 0.0
        dev.tick(0.0)

    def send(self, name: str, **fields: int) -> None:
        self.t_s += 0.01
        self.dev.handle_rx(wp.encode("HEARTBEAT") + wp.encode(name, **fields), self.t_s)
        self.dev.tick(self.t_s)

    def idle(self, duration_s: float) -> None:
        for _ in range(round(duration_s / 0.01)):
            self.send("HEARTBEAT")

    def uncalibrated(self) -> list[int]:
        """The wheels whose 1 mrad/s closed-loop setpoint the board refuses (as the doctor's
        probe: its targets stay 0)."""
        refused = []
        for wheel in range(wp.N_WHEELS):
            speeds = {f"w{i}_mrad_s": int(i == wheel) for i in range(wp.N_WHEELS)}
            self.send("SET_SPEEDS", **speeds)
            if self.dev.targets[wheel] == 0:
                refused.append(wheel)
            self.send("SET_SPEEDS", **dict.fromkeys(speeds, 0))
        return refused
