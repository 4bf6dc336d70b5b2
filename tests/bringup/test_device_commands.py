"""``gyrotens wheels spin``, ``servos jog|home`` and ``imu calibrate`` against the simulated
devices: each does what it says, refuses what is out of its limits before anything moves
(exit 2), and names the port it cannot open."""

import re

import pytest
from bringup_rig import config_text

from gyrohost.cli import main
from gyrohost.config import load_rig_config
from gyrohost.resources import shipped
from gyrohost.simrig.servo_emu import Mx12Bus

START_M = 0.43105229381822
"""The D-bar scene's start length of both strings (sim-rig's length_at_zero_m: position 0)."""


def write(tmp_path, ports):
    path = tmp_path / "rig.toml"
    path.write_text(config_text("sim-rig", ports))
    return str(path)


@pytest.fixture
def servo_bus():
    """The sim-rig's two MX-12W servos on an emulated bus of their own, at position 0."""
    bus = Mx12Bus(list(load_rig_config(shipped("config", "sim-rig")).servos.servo)).start()
    yield bus
    bus.close()


def test_wheels_spin_reaches_the_speed_and_ramps_down(tmp_path, rig_ports, capsys):
    config = write(tmp_path, rig_ports)
    argv = ["wheels", "spin", "--config", config, "--wheel", "2", "--speed", "10", "--time", "1"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    measured = float(re.search(r"wheel 2: measured (\S+) rad/s", out).group(1))
    assert abs(measured - 10.0) < 1.0, out  # the emulated motor's lag is 0.05 s: settled
    assert out.rstrip().endswith("wheel 2: stopped"), out


def test_wheels_calibrate_keeps_the_positional_port_with_a_deprecation_line(rig_ports, capsys):
    status = main(["wheels", "calibrate", rig_ports["wheels"], "--wheel", "1", "--no-save"])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    assert "PORT is deprecated, use --port PORT" in captured.err
    assert "wheel 1: ENC_OFFSET_M1 = " in captured.out and "saved" not in captured.out


def test_wheels_spin_refuses_a_fast_or_long_spin_before_the_port_opens(tmp_path, capsys):
    missing = str(tmp_path / "ttyACM9")
    argv = ["wheels", "spin", "--port", missing, "--wheel", "0"]
    assert main([*argv, "--speed", "10"]) == 2
    assert "no such device" in capsys.readouterr().err
    config = write(tmp_path, {"imu": "x", "servos": "x", "wheels": "/dev/null"})
    assert main(["wheels", "spin", "--config", config, "--wheel", "0", "--speed", "50"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("gyrotens wheels: error: speed 50 rad/s: 0 < |speed| <= 20"), err
    assert main(["wheels", "spin", "--config", config, "--wheel", "0", "--speed", "5",
                 "--time", "60"]) == 2  # fmt: skip
    assert "time 60 s: 0 < time <= 10 s" in capsys.readouterr().err


def test_servos_jog_and_home_move_within_the_limits(tmp_path, servo_bus, capsys):
    config = write(tmp_path, {"imu": "x", "wheels": "x", "servos": servo_bus.slave_path})
    assert main(["servos", "jog", "--config", config, "--servo", "s24", "--by-m", "0.01"]) == 0
    out = capsys.readouterr().out
    assert f"servo 's24': {START_M:.4f} m -> {START_M + 0.01:.4f} m" in out, out
    reached = float(re.search(r"servo 's24': at (\S+) m, holding", out).group(1))
    assert abs(reached - (START_M + 0.01)) < 2e-4  # two steps of a 10 mm pulley: 31 um
    argv = ["servos", "jog", "--config", config, "--servo", "s13", "--by-m", "0.05"]
    assert main(argv) == 2  # s13's max_length_m is 0.45
    assert "0.4811" in capsys.readouterr().err
    assert main(["servos", "home", "--config", config]) == 0
    out = capsys.readouterr().out
    for name in ("s13", "s24"):
        reached = float(re.search(rf"servo '{name}': at (\S+) m, holding", out).group(1))
        assert abs(reached - START_M) < 2e-4, out


def test_servos_refuse_to_move_with_uncalibrated_zeros(tmp_path, servo_bus, capsys):
    path = tmp_path / "lab.toml"
    path.write_text(config_text("lab-rig", {"imu": "x", "wheels": "x",
                                            "servos": servo_bus.slave_path}))  # fmt: skip
    assert main(["servos", "home", "--config", str(path)]) == 2
    err = capsys.readouterr().err
    assert "servos.servo[0].zero_position" in err and "gyrotens servos zero" in err, err


def test_imu_calibrate_removes_the_accelerometer_bias(tmp_path, rig_ports, capsys):
    config = write(tmp_path, rig_ports)
    assert main(["imu", "calibrate", "--config", config, "--wait", "0.2"]) == 0
    out = capsys.readouterr().out
    assert "keep it level and still" in out, out
    after = re.search(r"after: mean specific force \((\S+), (\S+), (\S+)\)", out)
    # the emulated IMU lies level: its x and y means are the bias left, plus the noise of a
    # 1 s mean (0.057 m/s^2 / sqrt(100 samples) = 0.006 m/s^2; 5 sigma is 0.03)
    assert abs(float(after.group(1))) < 0.03 and abs(float(after.group(2))) < 0.03, out
