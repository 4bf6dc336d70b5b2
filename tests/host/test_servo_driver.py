"""String servo driver against the emulated MX-12W bus over a pty."""

import math
import time
from dataclasses import replace

import pytest

from gyrohost.config import ConfigError, ServoBusConfig, ServoConfig
from gyrohost.drivers.errors import (
    ServoCommError,
    ServoError,
    ServoFaultError,
    ServoLimitError,
    ServoTimeoutError,
)
from gyrohost.drivers.mx12 import Addr, string_speed_per_unit
from gyrohost.drivers.servos import StringServoBus
from gyrohost.simrig.config import ServoEmuConfig
from gyrohost.simrig.servo_emu import Mx12Bus

LEFT = ServoConfig(
    name="left", id=1, pulley_radius_m=0.01, zero_position=0, length_at_zero_m=0.30,
    length_sign=1, min_length_m=0.10, max_length_m=0.50, max_speed_m_s=0.2,
)  # fmt: skip
RIGHT = replace(LEFT, name="right", id=2, zero_position=500, length_sign=-1)
STEP_M = 2 * math.pi * 0.01 / 4096
EMU = ServoEmuConfig(return_delay_us=0)

PTY_REPLY_TIMEOUT_S = 1.0  # generous: the emulator thread shares a loaded CPU
SHORT_TIMEOUT_S = 0.05  # where a timeout is the expected outcome


@pytest.fixture
def rig():
    made = []

    def make(read_mode="bulk", emu=EMU, servos=(LEFT, RIGHT), configure=True):
        device = Mx12Bus(servos, emu).start()
        cfg = ServoBusConfig(
            port=device.slave_path,
            read_mode=read_mode,
            reply_timeout_s=PTY_REPLY_TIMEOUT_S,
            servo=servos,
        )
        bus = StringServoBus(cfg).open()
        made.append((device, bus))
        if configure:
            bus.configure()
        return device, bus

    yield make
    for device, bus in made:
        bus.close()
        device.close()
        assert device.loop_error is None


def wait_until_at(bus, lengths_m, timeout_s=2.0):
    """Read states until every length is within one step of its goal (or time is up)."""
    deadline = time.monotonic() + timeout_s
    while True:
        states = bus.read_states()
        done = all(abs(s.length_m - g) <= STEP_M for s, g in zip(states, lengths_m, strict=True))
        if done or time.monotonic() > deadline:
            return states
        time.sleep(0.01)


def wait_for(condition, timeout_s=1.0):
    """The sync write has no reply and a pty delivers asynchronously: wait for its effect."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "condition not met in time"
        time.sleep(0.002)


@pytest.mark.parametrize("read_mode", ["bulk", "per_servo"])
def test_configure_command_and_read_back(rig, read_mode):
    device, bus = rig(read_mode)
    assert bus.low_latency is False  # the pty refuses the ioctl; the driver carries on
    for servo in device.servos.values():
        assert servo.mode == "multi-turn" and servo.torque_on
    assert [s.length_m for s in bus.read_states()] == pytest.approx([0.30, 0.30])
    goals = bus.command_lengths({"left": 0.32, "right": 0.27})
    # Lengthening turns left forwards; shortening turns right (length_sign -1) forwards too.
    assert goals == {"left": round(0.02 / STEP_M), "right": 500 + round(0.03 / STEP_M)}
    states = wait_until_at(bus, [0.32, 0.27])
    assert [s.length_m for s in states] == pytest.approx([0.32, 0.27], abs=STEP_M)
    # the shaft closes in on its goal through the servo's lag: a read within a count of the
    # goal has it within a count and a half, and on until it stops
    assert device.string_length_m(1) == pytest.approx(0.32, abs=1.5 * STEP_M)
    assert device.string_length_m(2) == pytest.approx(0.27, abs=1.5 * STEP_M)


def test_negative_multi_turn_positions_read_back_signed(rig):
    device, bus = rig()
    bus.command_lengths([0.15, 0.45])  # left below its zero, right past -5000 steps
    states = wait_until_at(bus, [0.15, 0.45])
    assert states[0].position_steps < -9000 and states[1].position_steps < -9000
    assert [s.length_m for s in states] == pytest.approx([0.15, 0.45], abs=STEP_M)


def test_speed_limit_is_sent_and_never_exceeded(rig):
    device, bus = rig()
    bus.command_lengths([0.40, 0.30], speeds_m_s=[0.02, 0.2])
    unit = string_speed_per_unit(LEFT)
    expected_units = math.floor(0.02 / unit)
    wait_for(lambda: device.servos[1].word(Addr.MOVING_SPEED) == expected_units)
    l0, t0 = device.string_length_m(1), time.monotonic()
    time.sleep(0.2)
    l1, t1 = device.string_length_m(1), time.monotonic()
    assert 0 < l1 - l0 <= 0.02 * (t1 - t0) * 1.05
    assert 0 < bus.read_states()[0].speed_m_s <= 0.02


@pytest.mark.parametrize(
    ("lengths", "speeds", "message"),
    [
        ([0.55, 0.3], None, r"servo 'left' \(ID 1\): string length 0.5500 m .* \[0.1, 0.5\] m"),
        ([0.3, 0.05], None, r"servo 'right' \(ID 2\): string length 0.0500 m"),
        ([float("nan"), 0.3], None, "not finite"),
        ([0.3, 0.3], [0.3, 0.1], r"servo 'left' \(ID 1\): string speed 0.3 m/s .* 0.2\] m/s"),
        ([0.3, 0.3], [0.1, 0.0], r"servo 'right' \(ID 2\): string speed 0.0 m/s"),
        ({"middle": 0.3}, None, "unknown servo"),
        ([0.3], None, "1 values for 2 servos"),
    ],
)
def test_commands_outside_limits_are_refused_and_nothing_is_sent(rig, lengths, speeds, message):
    device, bus = rig()
    seen = device.packets_seen
    with pytest.raises(ServoLimitError, match=message):
        bus.command_lengths(lengths, speeds)
    assert device.packets_seen == seen


def test_limits_that_map_outside_the_multi_turn_range_are_refused():
    wide = replace(LEFT, max_length_m=2.0)  # 1.7 m at r = 1 cm is about 27 turns
    with pytest.raises(ServoLimitError, match=r"servo 'left' \(ID 1\): length limit 2.0 m"):
        StringServoBus(ServoBusConfig(port="/dev/null", servo=(wide,)))


def test_overload_from_tension_is_a_named_fault_and_hold_recovers(rig):
    device, bus = rig()
    device.set_tension(1, 5.0)  # 0.05 N m against 0.2 N m stall: fine
    time.sleep(0.02)
    left = bus.read_states()[0]
    assert left.load_fraction == pytest.approx(-0.25, abs=0.002)  # resists lengthening (CW)
    device.set_tension(1, 30.0)  # 0.3 N m: overload
    time.sleep(0.02)
    with pytest.raises(ServoFaultError, match=r"servo 'left' \(ID 1\) reports: overload") as info:
        bus.read_states()
    assert info.value.faults == ("overload",) and len(info.value.states) == 2
    assert not device.servos[1].torque_on  # the MX shuts its torque down
    device.set_tension(1, 2.0)
    states = bus.hold()
    assert states[0].faults == ("overload",)
    assert device.servos[1].torque_on
    assert bus.read_states()[0].faults == ()


def test_right_servo_load_sign_follows_its_length_sign(rig):
    device, bus = rig()
    device.set_tension(2, 5.0)
    time.sleep(0.02)
    assert bus.read_states()[1].load_fraction == pytest.approx(0.25, abs=0.002)


def test_injected_overload_at_run_time_and_by_configuration(rig):
    device, bus = rig()
    device.set_overload(2, True)
    with pytest.raises(ServoFaultError, match=r"'right' \(ID 2\) reports: overload"):
        bus.read_states()
    device, bus = rig(emu=replace(EMU, overload_ids=(1,)), configure=False)
    with pytest.raises(ServoFaultError, match=r"'left' \(ID 1\).*ping: overload"):
        bus.configure()


@pytest.mark.parametrize("read_mode", ["bulk", "per_servo"])
def test_a_silent_servo_times_out(rig, read_mode):
    device, bus = rig(read_mode)
    device.set_no_reply(1, True)
    bus.reply_timeout_s = SHORT_TIMEOUT_S
    with pytest.raises(ServoCommError, match=r"'left' \(ID 1\).*no status packet") as info:
        bus.read_states()
    assert info.value.servo_id == 1
    device.set_no_reply(1, False)
    bus.reply_timeout_s = PTY_REPLY_TIMEOUT_S
    assert len(bus.read_states()) == 2


@pytest.mark.parametrize("read_mode", ["bulk", "per_servo"])
def test_goals_go_out_while_a_silent_servo_is_awaited(rig, read_mode):
    device, bus = rig(read_mode)
    device.set_no_reply(1, True)
    bus.reply_timeout_s = SHORT_TIMEOUT_S
    sent = []

    def send_goal():
        if not sent:
            sent.append(bus.command_lengths({"right": 0.35}))

    bus.on_reply_wait(send_goal)
    with pytest.raises(ServoTimeoutError, match=r"'left' \(ID 1\)"):
        bus.read_states()
    assert sent and device.servos[2]._goal() == sent[0]["right"]
    bus.on_reply_wait(None)
    device.set_no_reply(1, False)
    bus.reply_timeout_s = PTY_REPLY_TIMEOUT_S
    assert len(bus.read_states()) == 2  # no packet was cut into


@pytest.mark.parametrize("read_mode", ["bulk", "per_servo"])
def test_hold_holds_the_servos_that_answer_and_names_the_silent_one(rig, read_mode):
    device, bus = rig(read_mode)
    bus.set_torque(False)
    device.set_no_reply(1, True)
    bus.reply_timeout_s = SHORT_TIMEOUT_S
    with pytest.raises(ServoTimeoutError, match=r"'left' \(ID 1\).*no status packet"):
        bus.hold()
    assert device.servos[2].torque_on and not device.servos[1].torque_on


def test_no_reply_by_configuration(rig):
    device, bus = rig(emu=replace(EMU, no_reply_ids=(2,)), configure=False)
    bus.reply_timeout_s = SHORT_TIMEOUT_S
    with pytest.raises(ServoCommError, match=r"'right' \(ID 2\).*ping"):
        bus.configure()


def test_corrupt_reply_is_a_comm_error_then_the_bus_recovers(rig):
    device, bus = rig()
    device.faults.corrupt_next(1)
    bus.reply_timeout_s = SHORT_TIMEOUT_S
    with pytest.raises(ServoCommError, match="left"):
        bus.read_states()
    time.sleep(0.05)
    bus.reply_timeout_s = PTY_REPLY_TIMEOUT_S
    assert len(bus.read_states()) == 2


def test_stalled_link_times_out_then_the_burst_is_flushed(rig):
    device, bus = rig()
    device.faults.stall_for(0.3, time.monotonic())
    bus.reply_timeout_s = SHORT_TIMEOUT_S
    with pytest.raises(ServoCommError, match="no status packet"):
        bus.read_states()
    time.sleep(0.35)
    bus.reply_timeout_s = PTY_REPLY_TIMEOUT_S
    assert len(bus.read_states()) == 2  # the SDK clears the late burst before asking again


def test_reply_timeout_must_be_positive(rig):
    _, bus = rig(configure=False)
    with pytest.raises(ServoLimitError, match="reply timeout -1"):
        bus.reply_timeout_s = -1.0


def test_wrong_model_is_refused(rig):
    device, bus = rig(configure=False)
    device.servos[2].table[0] = 29  # MX-28
    with pytest.raises(ServoError, match=r"'right' \(ID 2\): model 29, expected MX-12W"):
        bus.ping_all()


def test_torque_off_and_on(rig):
    device, bus = rig()
    bus.set_torque(False)
    assert not any(s.torque_on for s in device.servos.values())
    bus.set_torque(True)
    assert all(s.torque_on for s in device.servos.values())


def test_unopenable_port_is_a_servo_error():
    bus = StringServoBus(ServoBusConfig(port="/nonexistent/ttyUSB9", servo=(LEFT,)))
    with pytest.raises(ServoError, match="cannot open /nonexistent/ttyUSB9"):
        bus.open()


def test_emulator_refuses_fault_ids_that_are_not_on_the_bus():
    with pytest.raises(ConfigError, match=r"sim.servos.no_reply_ids: IDs \[7\] are not on the bus"):
        Mx12Bus((LEFT, RIGHT), replace(EMU, no_reply_ids=(7,)))


def test_emulator_shuts_down_cleanly():
    device = Mx12Bus((LEFT,), EMU).start()
    device.close()
    device.close()  # idempotent
    assert device.link.write(b"x") == 0 and device.link.read(0.01) == b""


def test_a_length_on_the_limit_is_commanded_within_it(rig):
    device, bus = rig()
    # LEFT's 0.50 m is 13037.97 steps from its zero: the nearest step, 13038, is past the limit
    assert bus.command_lengths({"left": 0.50})["left"] == 13037
    one_ulp_past = math.nextafter(0.50, 1.0)
    assert bus.command_lengths({"left": one_ulp_past})["left"] == 13037  # rounding: clamped
    assert bus.command_lengths({"left": 0.10 - 1e-12})["left"] == -13037  # and at the bottom
    with pytest.raises(ServoLimitError, match="outside the limit"):
        bus.command_lengths({"left": 0.50 + 1e-6})  # beyond rounding: refused
    states = wait_until_at(bus, [0.10, 0.30])
    assert 0.10 <= states[0].length_m <= 0.10 + STEP_M


@pytest.mark.parametrize("read_mode", ["bulk", "single"])
def test_goals_and_reads_are_stamped_when_their_packet_goes_out(rig, read_mode, monkeypatch):
    """Work before the write (the SDK's own, or a wait for the GIL) does not move the stamps: a
    goal's and a read's time is when its packet went to the OS, not when the call began."""
    _, bus = rig(read_mode)
    delay_s = 0.02
    clear = type(bus.port).clearPort
    monkeypatch.setattr(type(bus.port), "clearPort", lambda p: time.sleep(delay_s) or clear(p))
    called_ns = time.monotonic_ns()
    bus.command_lengths([0.30, 0.30])
    assert bus.goals_sent_ns >= called_ns + delay_s * 1e9
    called_ns = time.monotonic_ns()
    (state, *_) = bus.read_states()
    assert state.t_ns >= called_ns + delay_s * 1e9
