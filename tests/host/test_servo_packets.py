"""MX-12W servos on hand-built byte streams: word conversions, status packets the driver must
survive (through a scripted pty device), instruction packets the emulator must answer, and a
property test of the emulator's packet cutter."""

import math
import time

import pytest
import serial
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from gyrohost.config import ServoBusConfig, ServoConfig
from gyrohost.drivers.errors import ServoCommError, ServoFaultError
from gyrohost.drivers.mx12 import (
    FAULT_BITS,
    Addr,
    fault_names,
    int16_from_word,
    length_to_steps,
    sign_magnitude_from_signed,
    signed_from_sign_magnitude,
    steps_to_length,
    word_from_int16,
)
from gyrohost.drivers.servos import StringServoBus
from gyrohost.simrig.config import ServoEmuConfig
from gyrohost.simrig.pty_link import PtyDevice
from gyrohost.simrig.servo_emu import EmulatedMx12, Mx12Bus, Packet, PacketCutter, status_packet

SERVO = ServoConfig(name="left", id=3, pulley_radius_m=0.01, length_at_zero_m=0.3, max_length_m=0.6)

PTY_REPLY_TIMEOUT_S = 0.3  # long enough for a loaded CPU, short for the timeout cases


# --- conversions --------------------------------------------------------------------------------


def test_sixteen_bit_twos_complement():
    assert int16_from_word(60536) == -5000  # the SDK's raw read of a -5000 goal
    assert word_from_int16(-5000) == 60536
    assert int16_from_word(word_from_int16(-28672)) == -28672
    with pytest.raises(ValueError, match="signed 16-bit"):
        word_from_int16(40000)


def test_sign_magnitude():
    assert signed_from_sign_magnitude(0x400 | 100) == -100
    assert signed_from_sign_magnitude(100) == 100
    assert sign_magnitude_from_signed(-1023) == 0x7FF
    with pytest.raises(ValueError, match="10-bit"):
        sign_magnitude_from_signed(1024)


def test_fault_names_cover_every_bit():
    assert fault_names(0) == ()
    assert fault_names(0x7F) == tuple(FAULT_BITS.values())
    assert fault_names(0x21) == ("input voltage", "overload")


def test_length_and_steps_are_inverse_and_signed():
    for sign in (1, -1):
        servo = ServoConfig(
            name="s", id=1, pulley_radius_m=0.012, zero_position=-300, length_at_zero_m=0.25,
            length_sign=sign,
        )  # fmt: skip
        one_turn = 2 * math.pi * 0.012
        assert length_to_steps(servo, 0.25 + one_turn) == pytest.approx(-300 + sign * 4096)
        assert steps_to_length(servo, length_to_steps(servo, 0.4)) == pytest.approx(0.4)


# --- the driver on scripted status packets ------------------------------------------------------


class ScriptedServo(PtyDevice):
    """Answers each instruction packet with the next scripted reply (bytes), or not at all."""

    def __init__(self, replies):
        super().__init__()
        self.replies = list(replies)
        self.received = []
        self.cutter = PacketCutter()

    def handle_rx(self, data, now_s):
        for packet in self.cutter.feed(data):
            self.received.append(packet)
            if self.replies:
                self.link.write(self.replies.pop(0))

    def tick(self, now_s):
        pass


@pytest.fixture
def scripted():
    made = []

    def make(*replies):
        device = ScriptedServo(replies).start()
        cfg = ServoBusConfig(
            port=device.slave_path, reply_timeout_s=PTY_REPLY_TIMEOUT_S, servo=(SERVO,)
        )
        bus = StringServoBus(cfg).open()
        made.append((device, bus))
        return device, bus

    yield make
    for device, bus in made:
        bus.close()
        device.close()


OK = status_packet(3, 0)


def test_clean_reply(scripted):
    device, bus = scripted(OK)
    bus.set_torque(True)
    assert device.received == [Packet(3, 0x03, bytes([Addr.TORQUE_ENABLE, 1]), True)]


STATE = bytes([0x78, 0xEC, 0x05, 0x04, 0x0A, 0x00])  # -5000 steps, speed -5, load +10


def test_garbage_before_the_reply_is_skipped(scripted):
    device, bus = scripted(b"\x00\x13\xff\x42" + status_packet(3, 0, STATE))
    (state,) = bus.read_states()
    assert state.position_steps == -5000 and state.faults == ()
    assert len(device.received) == 1  # read once: the garbage cost no retry


def test_a_reply_from_another_id_is_ignored(scripted):
    other = bytes([0x10, 0x00, 0x00, 0x00, 0x00, 0x00])  # +16 steps: must not be read as ID 3
    device, bus = scripted(status_packet(9, 0, other) + status_packet(3, 0, STATE))
    (state,) = bus.read_states()
    assert state.servo_id == 3 and state.position_steps == -5000
    assert len(device.received) == 1


@pytest.mark.parametrize(
    ("reply", "message"),
    [
        (OK[:-1] + bytes([OK[-1] ^ 0xFF]), "Incorrect status packet"),  # bad checksum
        (OK[:4], "Incorrect status packet"),  # truncated
        (b"", "There is no status packet"),  # silence
    ],
)
def test_bad_replies_raise_comm_errors_naming_the_servo(scripted, reply, message):
    _, bus = scripted(reply)
    with pytest.raises(ServoCommError, match=f"servo 'left' \\(ID 3\\).*{message}") as info:
        bus.set_torque(True)
    assert info.value.servo_id == 3


@pytest.mark.parametrize(("bit", "name"), list(FAULT_BITS.items()))
def test_each_error_bit_raises_the_named_fault(scripted, bit, name):
    _, bus = scripted(status_packet(3, bit))
    with pytest.raises(ServoFaultError, match=name) as info:
        bus.set_torque(True)
    assert info.value.faults == (name,)


def test_fault_bits_in_a_read_reach_the_state(scripted):
    _, bus = scripted(status_packet(3, 0x24, STATE))
    with pytest.raises(ServoFaultError, match="overheating, overload") as info:
        bus.read_states()
    (state,) = info.value.states
    assert state.position_steps == -5000
    assert state.faults == ("overheating", "overload")
    assert state.load_fraction == pytest.approx(0.010)
    assert state.speed_m_s < 0


# --- the emulator on hand-built instruction packets ---------------------------------------------


@pytest.fixture
def wire():
    """An emulated bus polled by hand and the raw serial port on its pty."""
    emu = ServoEmuConfig(return_delay_us=0)
    device = Mx12Bus([SERVO, ServoConfig(name="right", id=4, pulley_radius_m=0.01)], emu)
    port = serial.Serial(device.slave_path, timeout=0.02)
    clock = [0.0]

    def exchange(raw: bytes) -> list[Packet]:
        port.write(raw)
        port.flush()
        time.sleep(0.002)
        clock[0] += 0.001
        device.poll(now_s=clock[0], timeout_s=0.05)
        reply = b""
        while chunk := port.read(256):  # a pty delivers asynchronously: read until quiet
            reply += chunk
        return PacketCutter().feed(reply)

    yield device, exchange
    port.close()
    device.close()


def test_emulator_ping_and_read(wire):
    device, exchange = wire
    assert exchange(Packet(3, 0x01, b"", True).encode()) == [Packet(3, 0, b"", True)]
    (reply,) = exchange(Packet(3, 0x02, bytes([Addr.MODEL, 2]), True).encode())
    assert reply.params == (104).to_bytes(2, "little")


@pytest.mark.parametrize(
    ("packet", "error"),
    [
        (Packet(3, 0x03, bytes([Addr.PRESENT_POSITION, 0, 0]), True), 0x08),  # read-only
        (Packet(3, 0x02, bytes([70, 10]), True), 0x08),  # past the table end
        (Packet(3, 0x07, b"", True), 0x40),  # unknown instruction
        (Packet(3, 0x03, bytes([Addr.GOAL_POSITION, 0x00, 0x20]), True), 0x02),  # 8192 > 4095
    ],
)
def test_emulator_error_bits(wire, packet, error):
    _, exchange = wire
    (reply,) = exchange(packet.encode())
    assert reply.instruction == error  # the status packet's error byte sits there


def test_emulator_answers_a_bad_checksum_with_the_checksum_bit(wire):
    device, exchange = wire
    raw = bytearray(Packet(3, 0x01, b"", True).encode())
    raw[-1] ^= 0x55
    (reply,) = exchange(b"\x00\xff" + bytes(raw))
    assert reply.instruction == 0x10 and device.bad_checksums == 1


def test_emulator_status_return_level(wire):
    _, exchange = wire
    assert exchange(Packet(3, 0x03, bytes([Addr.STATUS_RETURN, 1]), True).encode()) != []
    assert exchange(Packet(3, 0x03, bytes([25, 1]), True).encode()) == []  # LED: no status
    assert len(exchange(Packet(3, 0x02, bytes([Addr.ID, 1]), True).encode())) == 1
    exchange(Packet(3, 0x03, bytes([Addr.STATUS_RETURN, 0]), True).encode())
    assert exchange(Packet(3, 0x02, bytes([Addr.ID, 1]), True).encode()) == []
    assert len(exchange(Packet(3, 0x01, b"", True).encode())) == 1  # ping always answers


def test_emulator_sync_write_and_bulk_read(wire):
    device, exchange = wire
    sync = bytes([Addr.MOVING_SPEED, 2, 3, 10, 0, 4, 20, 0])
    assert exchange(Packet(0xFE, 0x83, sync, True).encode()) == []
    bulk = bytes([0, 2, 4, Addr.MOVING_SPEED, 1, 3, Addr.ID])
    first, second = exchange(Packet(0xFE, 0x92, bulk, True).encode())
    assert (first.servo_id, first.params) == (4, bytes([20, 0]))
    assert (second.servo_id, second.params) == (3, bytes([3]))


# --- property: the emulator's packet cutter ----------------------------------------------------

packet_strategy = st.builds(
    lambda i, inst, params: Packet(i, inst, params, True).encode(),
    st.integers(0, 0xFE),
    st.integers(0, 0xFF),
    st.binary(max_size=12),
)
noise_strategy = st.one_of(
    st.binary(max_size=24),
    packet_strategy.map(lambda p: p[: len(p) - 2]),  # truncated
    packet_strategy.map(lambda p: p[:-1] + bytes([p[-1] ^ 0x01])),  # bad checksum
    st.just(b"\xff\xff\xff"),
)


def fake_packet_at(stream: bytes, starts: set[int]) -> bool:
    """True if a position that is not an embedded packet parses as a valid packet."""
    for i in range(len(stream) - 5):
        if i in starts or stream[i : i + 2] != b"\xff\xff" or stream[i + 2] == 0xFF:
            continue
        total = stream[i + 3] + 4
        if stream[i + 3] >= 2 and i + total <= len(stream):
            if stream[i + total - 1] == (~sum(stream[i + 2 : i + total - 1])) & 0xFF:
                return True
    return False


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(noise_strategy, packet_strategy), max_size=10), st.integers(1, 50))
def test_every_embedded_packet_is_recovered(pieces, chunk):
    stream = bytearray()
    starts = set()
    for noise, packet in pieces:
        stream += noise
        starts.add(len(stream))
        stream += packet
    stream += bytes(260)  # the line goes on: a bogus length waiting for bytes is resolved
    assume(not fake_packet_at(bytes(stream), starts))
    cutter = PacketCutter()
    got = []
    for pos in range(0, len(stream), chunk):
        got += [p.encode() for p in cutter.feed(bytes(stream[pos : pos + chunk])) if p.checksum_ok]
    assert got == [packet for _, packet in pieces]


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=400))
def test_cutter_never_raises_on_random_bytes(data):
    assert all(isinstance(p, Packet) for p in PacketCutter().feed(data))


# --- the emulator's motion ----------------------------------------------------------------------


def _move(servo: EmulatedMx12, goal: int) -> None:
    servo.write(Addr.GOAL_POSITION, goal.to_bytes(2, "little"))
    for _ in range(2000):  # 2 s at 1 ms: far longer than the move at the no-load speed
        servo.advance(1e-3)


def test_a_move_within_the_p_band_is_a_first_order_lag_whatever_the_ticks():
    """200 steps, under the factory P gain's band (427 steps at 470 rpm): the error decays
    as exp(-t / lag), lag = 50 / (P rpm) = 13.3 ms, exactly at uneven ticks."""
    servo = EmulatedMx12(3, ServoEmuConfig(hold_band_steps=0.0), SERVO)
    servo.write(Addr.TORQUE_ENABLE, b"\x01")
    start = servo.position_steps  # the calibrated zero: no band to sit in
    servo.write(Addr.GOAL_POSITION, int(start + 200).to_bytes(2, "little"))
    lag, t = 50.0 / (8 * 470.0), 0.0
    for dt in (0.0003, 0.0021, 0.0007, 0.011, 0.004):
        servo.advance(dt)
        t += dt
        assert servo.position_steps - start == pytest.approx(200 * (1 - math.exp(-t / lag)))


@pytest.mark.parametrize("speed_units", [0, 100])
def test_a_long_move_runs_at_the_speed_limit_then_lags(speed_units):
    """5000 steps (multi-turn): at the speed limit (no-load 470 rpm, or the moving speed's 91.6
    rpm) until the P gain's output falls below it, at an error of speed x lag; then the lag."""
    servo = EmulatedMx12(3, ServoEmuConfig(hold_band_steps=0.0), SERVO)
    servo.write(Addr.CW_LIMIT, bytes((0xFF, 0x0F, 0xFF, 0x0F)))
    servo.write(Addr.TORQUE_ENABLE, b"\x01")
    servo.write(Addr.MOVING_SPEED, speed_units.to_bytes(2, "little"))
    start = servo.position_steps
    servo.write(Addr.GOAL_POSITION, int(start + 5000).to_bytes(2, "little"))
    rpm = 470.0 if speed_units == 0 else speed_units * 0.916
    speed, lag = rpm / 60 * 4096, 50.0 / (8 * 470.0)
    linear_s = (5000 - speed * lag) / speed
    servo.advance(0.5 * linear_s)
    assert servo.position_steps - start == pytest.approx(0.5 * linear_s * speed)
    servo.advance(0.5 * linear_s + lag)
    assert servo.position_steps - start == pytest.approx(5000 - speed * lag * math.exp(-1))


def test_an_emulated_servo_stops_within_its_hold_band_and_holds_there():
    servo = EmulatedMx12(3, ServoEmuConfig(hold_band_steps=0.5, seed=7), SERVO)
    assert 0 < abs(servo.position_steps - SERVO.zero_position) <= 0.5  # the start is held too
    servo.write(Addr.TORQUE_ENABLE, b"\x01")
    offsets = []
    for goal in (1000, 1400, 1200):
        _move(servo, goal)
        offsets.append(servo.position_steps - goal)
        servo.advance(1.0)  # held: it does not creep onto the goal
        assert servo.position_steps - goal == offsets[-1]
        present, _ = servo.read(Addr.PRESENT_POSITION, 2)
        moving, _ = servo.read(Addr.MOVING, 1)
        assert int.from_bytes(present, "little") == goal and moving == b"\x00"
    assert all(0 < abs(e) <= 0.5 for e in offsets) and len(set(offsets)) == 3
    servo.position_steps = 1300.0  # pushed out of its band by hand: it moves back
    _move(servo, 1200)
    assert abs(servo.position_steps - 1200) <= 0.5

    exact = EmulatedMx12(3, ServoEmuConfig(hold_band_steps=0.0), SERVO)
    exact.write(Addr.TORQUE_ENABLE, b"\x01")
    _move(exact, 1000)  # no band: the lag closes in on the goal (150 lags in 2 s)
    assert exact.position_steps == pytest.approx(1000.0, abs=1e-9)


def test_a_goal_moves_the_servo_from_the_poll_that_read_it():
    """The rig's loop wakes when bytes come: a goal read at a poll 5 ms after the last one moves
    the servo from then, not from the last poll (before it was sent): at the next poll, 1 ms
    on, it has moved by the lag over 1 ms, not over 6 ms."""
    device = Mx12Bus([SERVO], ServoEmuConfig(hold_band_steps=0.0))
    port = serial.Serial(device.slave_path, timeout=0.02)
    try:
        servo = device.servos[3]
        servo.write(Addr.TORQUE_ENABLE, b"\x01")
        device.poll(now_s=0.0)
        start = servo.position_steps
        goal = int(start) + 100
        port.write(Packet(3, 0x03, bytes([Addr.GOAL_POSITION, *goal.to_bytes(2, "little")]),
                          True).encode())  # fmt: skip
        port.flush()
        time.sleep(0.01)
        device.poll(now_s=0.005)
        assert servo.position_steps == start
        device.poll(now_s=0.006)
        moved = servo.position_steps - start
        assert moved == pytest.approx((goal - start) * -math.expm1(-0.001 / (50 / (8 * 470))))
    finally:
        port.close()
        device.close()
