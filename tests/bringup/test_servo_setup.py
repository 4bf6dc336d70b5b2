"""``gyrotens servos id|zero`` (and the old ``servo-setup``) against the emulated MX-12W bus: a
lone servo's new ID and baud rate confirmed by PING, two servos refused, the zero read and the
sign checked by a confirmed move."""

import pytest
from bringup_rig import config_text

from gyrohost.cli import main
from gyrohost.config import ServoConfig
from gyrohost.drivers.mx12 import Addr
from gyrohost.simrig.servo_emu import Mx12Bus

FAST = ["--scan-ids", "1-10", "--reply-timeout", "0.2"]  # a pty shares the CPU


def bus_of(*ids, **calibration):
    servos = [ServoConfig(f"s{i}", i, 0.01, **calibration) for i in ids]
    return Mx12Bus(servos).start()


def calibration_bus():
    """One emulated servo, ID 1 (the sim-rig's s13), its string 0.3 m at position 0."""
    return bus_of(1, length_at_zero_m=0.3, min_length_m=0.1, max_length_m=0.45)


def config_on(bus, tmp_path):
    """The sim-rig configuration with its servo bus on ``bus``'s pty."""
    path = tmp_path / "rig.toml"
    ports = {"imu": "emulator", "wheels": "emulator", "servos": bus.slave_path}
    path.write_text(config_text("sim-rig", ports))
    return path


ZERO = ["servos", "zero", "--servo", "s13", "--length-m", "0.3", "--config"]


def test_a_lone_servo_gets_its_new_id_and_baud_confirmed_by_ping(capsys):
    bus = bus_of(1)
    try:
        argv = ["servos", "id", "--port", bus.slave_path, "--new-id", "4"]
        assert main([*argv, "--new-baud", "57600", *FAST]) == 0
        out = capsys.readouterr().out
        assert "MX-12W: ID 1 at 1000000 baud -> ID 4 at 57600 baud (confirmed by PING)" in out
        servo = bus.servos[4]
        assert servo.table[Addr.ID] == 4 and servo.table[Addr.BAUD] == 34
    finally:
        bus.close()


def test_two_servos_on_the_bus_are_refused_and_keep_their_ids(capsys):
    bus = bus_of(1, 2)
    try:
        argv = ["servo-setup", "id", "--port", bus.slave_path, "--new-id", "4", *FAST]
        assert main(argv) == 2  # the old spelling, with its deprecation line
        err = capsys.readouterr().err
        assert "IDs [1, 2] answered (IDs 1..10): connect exactly one" in err
        assert "gyrotens servo-setup id: deprecated, use gyrotens servos id" in err
        assert sorted(bus.servos) == [1, 2]
    finally:
        bus.close()


@pytest.mark.parametrize(("observed", "sign"), [("y", 1), ("n", -1)])
def test_zero_reads_the_position_and_a_confirmed_move_tells_the_sign(
    tmp_path, monkeypatch, capsys, observed, sign
):
    bus = calibration_bus()
    try:
        with bus.lock:
            bus.servos[1].position_steps = 1500.0  # wound by hand to the measured length
        answers = iter(["y", observed])
        monkeypatch.setattr("builtins.input", lambda prompt: next(answers))
        status = main([*ZERO, str(config_on(bus, tmp_path))])
        out, err = capsys.readouterr()
        assert status == 0, err
        assert f"zero_position = 1500\nlength_at_zero_m = 0.3\nlength_sign = {sign}" in out
        emulated = bus.servos[1]
        # moved back: read within 2 counts of the goal, a count the position rounded
        assert abs(emulated.position_steps - 1500) < 2.5
        assert emulated.table[Addr.TORQUE_ENABLE] == 0 and emulated.word(Addr.TORQUE_LIMIT) == 1023
    finally:
        bus.close()


def test_zero_moves_nothing_without_confirmation(tmp_path, monkeypatch, capsys):
    bus = calibration_bus()
    try:
        monkeypatch.setattr("builtins.input", lambda prompt: "n")
        before = bus.servos[1].position_steps
        assert main([*ZERO, str(config_on(bus, tmp_path))]) == 2
        assert "not confirmed: nothing moved" in capsys.readouterr().err
        assert bus.servos[1].position_steps == before
    finally:
        bus.close()
