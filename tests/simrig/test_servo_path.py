"""The emulated servos' paths (servo_emu.ServoPath): straight pieces within a tolerance of the
servo's positions, which the truth steps its physics through."""

import numpy as np
import pytest

from gyrohost.config import ServoConfig
from gyrohost.drivers.mx12 import (
    P_GAIN_FACTORY,
    Addr,
    position_lag_s,
    steps_per_metre,
    steps_to_length,
)
from gyrohost.simrig.config import ServoEmuConfig
from gyrohost.simrig.servo_emu import PATH_TOLERANCE_STEPS, Mx12Bus, ServoPath

SERVO = ServoConfig(name="left", id=1, pulley_radius_m=0.01, length_at_zero_m=0.4, string="s13")


def test_a_path_keeps_only_its_bends():
    path = ServoPath()
    for t, p in [(0.0, 0.0), (0.001, 0.0), (0.002, 0.0), (0.003, 10.0), (0.004, 20.0),
                 (0.005, 25.0), (0.006, 25.0)]:  # fmt: skip
        path.add(t, p)
    assert list(path.t_s) == [0.0, 0.002, 0.004, 0.005, 0.006]
    assert path.turns(0.0, 0.006) == [0.002, 0.004, 0.005]
    assert path.steps_at(0.0035) == pytest.approx(15.0)


def test_a_curve_is_kept_within_the_tolerance_in_fewer_pieces():
    """A lag's curve sampled every 0.1 ms: the path passes within the tolerance of every
    sample, with far fewer points (a piece ends only where the curve leaves its line)."""
    path = ServoPath()
    t = np.arange(0.0, 0.1, 1e-4)
    curve = 200.0 * (1.0 - np.exp(-t / 0.0133))
    for ti, pi in zip(t, curve, strict=True):
        path.add(float(ti), float(pi))
    off = np.array([path.steps_at(ti) for ti in t]) - curve
    assert np.max(np.abs(off)) <= PATH_TOLERANCE_STEPS
    assert len(path.t_s) < len(t) / 5


def test_a_move_bends_where_it_starts_and_where_it_stops():
    """200 steps at the factory P gain (a 13.3 ms lag): the path follows the lag from the
    tick the goal came in (within the tolerance at the ticks, where the emulator knows its
    position) and stops within its hold band."""
    bus = Mx12Bus([SERVO], ServoEmuConfig(hold_band_steps=0.5))
    try:
        servo = bus.servos[1]
        assert bus.lengths_at(0.0) == {1: bus.string_length_m(1)}  # before any tick: present
        servo.write(Addr.TORQUE_ENABLE, b"\x01")
        bus.tick(0.0)
        start = servo.position_steps
        servo.write(Addr.GOAL_POSITION, (200).to_bytes(2, "little"))
        for k in range(1, 201):
            bus.tick(k * 0.001)
        lag = position_lag_s(P_GAIN_FACTORY, 470.0)
        assert bus.turns_between(-1.0, 1.0)[0] == 0.0
        tolerance_m = PATH_TOLERANCE_STEPS / steps_per_metre(SERVO)
        for t in (0.002, 0.011, 0.03):
            steps = 200.0 - (200.0 - start) * np.exp(-t / lag)
            length = steps_to_length(SERVO, steps)
            assert bus.lengths_at(t)[1] == pytest.approx(length, abs=tolerance_m)
        assert bus.lengths_at(0.2)[1] == steps_to_length(SERVO, servo.position_steps)
        assert 0.0 < 200.0 - servo.position_steps <= 0.5
    finally:
        bus.close()


def test_a_long_hold_is_one_piece_checked_in_constant_time():
    """A minute held at 1 kHz ticks: one piece; each tick weighs against the slopes the piece
    allows, not against every point it absorbed (a list of them grew with the hold)."""
    path = ServoPath()
    for k in range(60_000):
        path.add(k * 1e-3, 100.0 + 1e-3 * np.sin(k))  # within the tolerance of a flat line
    assert len(path.t_s) == 2
    assert path._slopes[1] - path._slopes[0] < 2 * PATH_TOLERANCE_STEPS / 59.0


def test_a_goal_read_while_the_rig_catches_up_moves_the_servo_from_the_present():
    """The rig's loop, held up, polls the bus at a past truth step's end: a goal the host sent
    meanwhile came at the present, so the bus runs to the present and takes it there (read at
    the step's end, the goal moved the servo 50 ms before the host sent it)."""
    import time

    from gyrohost.simrig.servo_emu import INST_WRITE, Packet

    bus = Mx12Bus([SERVO], ServoEmuConfig(hold_band_steps=0.5))
    try:
        servo = bus.servos[1]
        servo.write(Addr.TORQUE_ENABLE, b"\x01")
        bus.poll(now_s=0.0)
        start = servo.position_steps
        goal = Packet(
            1, INST_WRITE, bytes([Addr.GOAL_POSITION]) + (200).to_bytes(2, "little"), True
        )
        with open(bus.slave_path, "wb", buffering=0) as port:
            port.write(goal.encode())
            time.sleep(0.05)  # the bytes in the pty before the polls
            bus.poll(now_s=0.01, present_s=0.06)
            bus.poll(now_s=0.07)
            assert servo.position_steps > start  # moving since the present
            assert bus.lengths_at(0.055)[1] == bus.lengths_at(0.0)[1]  # held until then
    finally:
        bus.close()
