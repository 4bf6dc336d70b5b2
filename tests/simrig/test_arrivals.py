"""Bytes a driver writes to an emulator, taken at the times they arrived (simrig.arrivals):
a servo moves to a goal from when its bytes came, not from the emulator's next poll."""

import os
import time

import pytest

from gyrohost.config import ServoConfig
from gyrohost.drivers.mx12 import Addr
from gyrohost.simrig.arrivals import ArrivalStamps
from gyrohost.simrig.config import ServoEmuConfig
from gyrohost.simrig.errors import PtyLinkError
from gyrohost.simrig.pty_link import PtyLink
from gyrohost.simrig.servo_emu import INST_WRITE, Mx12Bus, Packet

SERVO = ServoConfig(name="left", id=1, pulley_radius_m=0.01, length_at_zero_m=0.4, string="s13")
LATE_S = 0.1
"""How long the tests leave written bytes before they look: the stamps must not be that late."""


def test_bytes_come_with_the_time_they_arrived():
    link = PtyLink()
    stamps = ArrivalStamps(link.fileno())
    try:
        fd = os.open(link.slave_path, os.O_WRONLY)
        try:
            written_s = time.monotonic()
            os.write(fd, b"\x01\x02\x03")
            time.sleep(LATE_S)
            (arrived_s, data), *rest = stamps.take()
        finally:
            os.close(fd)
        assert data == b"\x01\x02\x03" and not rest
        assert written_s <= arrived_s < written_s + LATE_S / 2
        assert stamps.take() == []
    finally:
        stamps.close()
        link.close()


def test_a_stamped_goal_moves_the_servo_from_its_arrival_not_from_the_poll():
    """A goal written while the bus's owner was busy: polled ``LATE_S`` later, the servo's path
    leaves its start at the goal's arrival (it is far along by the midpoint), where a poll's
    time would hold it still until the poll."""
    origin_s = time.monotonic()
    bus = Mx12Bus([SERVO], ServoEmuConfig(hold_band_steps=0.5))
    try:
        servo = bus.servos[1]
        servo.write(Addr.TORQUE_ENABLE, b"\x01")
        bus.stamp_arrivals(origin_s)
        bus.poll(now_s=time.monotonic() - origin_s)
        start = bus.string_length_m(1)
        goal = Packet(
            1, INST_WRITE, bytes([Addr.GOAL_POSITION]) + (200).to_bytes(2, "little"), True
        )
        with open(bus.slave_path, "wb", buffering=0) as port:
            written_s = time.monotonic() - origin_s
            port.write(goal.encode())
            time.sleep(LATE_S)
            polled_s = time.monotonic() - origin_s
            bus.poll(now_s=polled_s)
        moved = bus.lengths_at(written_s + LATE_S / 2)[1] - start
        assert moved > 0.5 * (bus.string_length_m(1) - start) > 0.0
        assert bus.lengths_at(written_s)[1] == start
    finally:
        bus.close()


def test_bytes_stamped_after_a_poll_wait_for_a_later_one():
    origin_s = time.monotonic()
    bus = Mx12Bus([SERVO], ServoEmuConfig())
    try:
        bus.stamp_arrivals(origin_s)
        with open(bus.slave_path, "wb", buffering=0) as port:
            port.write(Packet(1, INST_WRITE, bytes([Addr.TORQUE_ENABLE, 1]), True).encode())
            time.sleep(LATE_S)
            bus.poll(now_s=-1.0)  # a poll for a time before the bytes came
            assert bus.packets_seen == 0
            bus.poll(now_s=time.monotonic() - origin_s)
            assert bus.packets_seen == 1
    finally:
        bus.close()


def test_a_stopped_child_is_named_not_a_silent_bus():
    link = PtyLink()
    stamps = ArrivalStamps(link.fileno(), link.slave_path)
    try:
        stamps._proc.kill()
        stamps._proc.wait()
        with pytest.raises(PtyLinkError, match=f"child of {link.slave_path} stopped"):
            stamps.take()
    finally:
        stamps.close()
        link.close()
