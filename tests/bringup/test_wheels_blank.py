"""The real wheel-board firmware with a blank EEPROM (simavr harness): the first spin-up is
refused naming ``gyrotens wheels calibrate``, ``gyrotens doctor`` fails every wheel's offset with
the line docs/bring-up.md shows, and after the calibration of one wheel that wheel spins."""

import re
from pathlib import Path

import pytest
from bringup_rig import config_text

from gyrohost.bringup.devices import wheel_board
from gyrohost.bringup.wheels import uncalibrated_wheels
from gyrohost.cli import main
from gyrohost.simrig import simavr

pytestmark = pytest.mark.fil

DOC = Path(__file__).resolve().parents[2] / "docs" / "bring-up.md"
NO = "/nonexistent/tty"


def test_a_blank_board_spins_once_its_wheel_is_calibrated(tmp_path, capsys):
    elf, harness = simavr.build_binaries(simavr.firmware_build())
    doc_line = next(
        line for line in DOC.read_text().splitlines() if line.startswith("FAIL  wheel offsets")
    )
    with simavr.Harness(elf, harness=harness) as board_sim:
        port = board_sim.pty
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
        assert abs(measured - 10.0) < 1.0 and "wheel 0: stopped" in out, out
