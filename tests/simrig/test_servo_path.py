"""The emulated servos' paths (servo_emu.ServoPath): straight between the times a servo changes
speed, which the truth steps its physics through."""

import pytest

from gyrohost.config import ServoConfig
from gyrohost.drivers.mx12 import Addr, steps_to_length
from gyrohost.simrig.config import ServoEmuConfig
from gyrohost.simrig.servo_emu import Mx12Bus, ServoPath

SERVO = ServoConfig(name="left", id=1, pulley_radius_m=0.01, length_at_zero_m=0.4, string="s13")


def test_a_path_keeps_only_its_bends():
    path = ServoPath()
    for t, p in [(0.0, 0.0), (0.001, 0.0), (0.002, 0.0), (0.003, 10.0), (0.004, 20.0),
                 (0.005, 25.0), (0.006, 25.0)]:  # fmt: skip
        path.add(t, p)
    assert list(path.t_s) == [0.0, 0.002, 0.004, 0.005, 0.006]
    assert path.turns(0.0, 0.006) == [0.002, 0.004, 0.005]
    assert path.steps_at(0.0035) == pytest.approx(15.0)


def test_a_move_bends_where_it_starts_and_where_it_reaches_its_goal():
    """200 steps at the MX-12W's 470 rpm (32,100 steps/s) take 6.2 ms: the path bends at the
    tick the goal came in and within the tick it arrives, and is straight between."""
    bus = Mx12Bus([SERVO], ServoEmuConfig(hold_band_steps=0.0))
    try:
        servo = bus.servos[1]
        assert bus.lengths_at(0.0) == {1: bus.string_length_m(1)}  # before any tick: present
        servo.write(Addr.TORQUE_ENABLE, b"\x01")
        bus.tick(0.0)
        servo.write(Addr.GOAL_POSITION, (200).to_bytes(2, "little"))
        for k in range(1, 11):
            bus.tick(k * 0.001)
        start, arrival = bus.turns_between(-1.0, 1.0)
        assert start == 0.0
        assert arrival == pytest.approx(200 / (470 / 60 * 4096), rel=1e-3)
        length = steps_to_length(SERVO, 100.0)  # halfway, at half the time
        assert bus.lengths_at(arrival / 2)[1] == pytest.approx(length, abs=1e-9)
        assert bus.lengths_at(0.01)[1] == pytest.approx(steps_to_length(SERVO, 200.0))
    finally:
        bus.close()
