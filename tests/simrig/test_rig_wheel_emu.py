"""The wheel-board client (drivers.wheelboard) against the wheel-board emulator over a pty."""

import array
import fcntl
import math
import os
import queue
import termios
import time
from dataclasses import replace

import numpy as np
import pytest
from control_beat import start_control_thread

from gyrohost.drivers import wheelboard as wb
from gyrohost.drivers import wheelproto as wp
from gyrohost.simrig.config import WheelEmuConfig
from gyrohost.simrig.wheel_emu import STOP_RAD_S, WheelBoardEmulator

SPIN = 74.87462492  # rad/s, 715 rpm
PATTERN = [SPIN, -SPIN, -SPIN, SPIN]


@pytest.fixture
def board():
    """A running emulator and a connected client; yields (emulator, client, fault events)."""
    device = WheelBoardEmulator(WheelEmuConfig(time_constant_s=0.03)).start()
    events: queue.Queue = queue.Queue()
    client = wb.WheelBoard(device.slave_path, on_fault=events.put)
    client.connect()
    client.control = start_control_thread(client)  # set: the host's control thread hangs
    # streaming: a reply can come sooner than the first frame's bits have crossed the wire
    assert wait_for(lambda: client.last_telemetry is not None)
    yield device, client, events
    client.close()
    device.close()
    assert device.loop_error is None


def wait_for(predicate, timeout_s=3.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.01)
    return False


def test_handshake_setpoints_reached_and_telemetry_rate(board):
    device, client, _ = board
    assert client.hello == {
        "proto_version": wp.PROTO_VERSION,
        "fw_major": 1,
        "fw_minor": 0,
        "n_wheels": 4,
        "n_params": len(wp.PARAMS),
        "tick_hz": 1000,
    }
    client.set_speeds(PATTERN)
    # ACCEL_RAD_S2 = 100: 0.75 s of ramp, then the 30 ms lag.
    assert wait_for(
        lambda: client.last_telemetry.omega_rad_s == pytest.approx(PATTERN, abs=0.05), 3.0
    ), client.last_telemetry
    assert device.wheel_speeds_rad_s() == pytest.approx(PATTERN, abs=0.05)
    assert client.last_telemetry.status_names == ["OUTPUTS_ENABLED"]
    while not client.telemetry.empty():
        client.telemetry.get_nowait()
    first = client.telemetry.get(timeout=1)
    time.sleep(0.5)
    samples = [client.telemetry.get_nowait() for _ in range(client.telemetry.qsize())]
    span_s = (samples[-1].t_us - first.t_us) * 1e-6
    assert 0.4 < span_s < 0.7
    assert len(samples) == pytest.approx(span_s * 500, abs=3)  # TELEMETRY_DIV 2: 500 Hz
    assert [s.seq for s in samples] == list(range(first.seq + 1, first.seq + 1 + len(samples)))
    assert client.stats()["bad_crc"] == 0


def test_the_longest_silence_to_the_board_is_measured(board):
    _, client, _ = board
    client.control.set()  # the driver's idle heartbeat alone
    time.sleep(0.2)
    assert 0.0 < client.silence_max_s < 0.25  # a beat every 50 ms
    client.heartbeat_period_s = 0.3  # the host pauses once
    time.sleep(0.15)  # the beater has started its 0.3 s wait
    client.heartbeat_period_s = 0.05
    time.sleep(0.3)
    assert 0.29 <= client.silence_max_s < 1.0


def test_heartbeat_loss_ramps_down_and_latches(board):
    device, client, events = board
    client.set_param("HEARTBEAT_MS", 100)
    client.set_speeds([20.0, -20.0, 0.0, 0.0])
    assert wait_for(lambda: abs(client.last_telemetry.omega_rad_s[0] - 20.0) < 0.1)
    client.control.set()  # the control thread hangs; queries go on
    assert client.get_param("HEARTBEAT_MS") == 100
    assert events.get(timeout=2.0) == ["HEARTBEAT_LOST"]
    assert "FAILSAFE" in client.last_telemetry.status_names
    # DECEL_RAD_S2 = 200: the setpoints reach 0 in 0.1 s; as the firmware, the board brakes on
    # until the encoder's last tick shows the wheel below STOP_RAD_S, then switches the drivers
    # off; the filtered estimate lags behind.
    assert wait_for(lambda: not any(device.enabled), 1.0)
    assert device.setpoints == [0, 0, 0, 0]
    speeds = device.wheel_speeds_rad_s()
    assert max(map(abs, speeds)) < 2 * STOP_RAD_S  # one count per tick is 0.38 rad/s
    assert speeds[0] > -STOP_RAD_S and speeds[1] < STOP_RAD_S  # never turned backwards
    assert max(map(abs, device.measured)) < 2 * STOP_RAD_S
    with pytest.raises(wb.WheelFaultError, match="HEARTBEAT_LOST"):
        client.check_faults()
    with pytest.raises(wb.DeviceError) as err:
        client.set_speeds([1.0, 0.0, 0.0, 0.0])
    assert err.value.name == "FAULT_ACTIVE" and str(err.value).endswith("latched: HEARTBEAT_LOST")
    client.control = start_control_thread(client)  # the control thread is back
    assert client.clear_faults(["HEARTBEAT_LOST"]) == ["HEARTBEAT_LOST"]
    client.set_speeds([1.0, 0.0, 0.0, 0.0])
    assert wait_for(lambda: abs(device.wheel_speeds_rad_s()[0] - 1.0) < 0.01)
    # telemetry carries the 14-bit encoder's quantisation: +-0.024 rad/s measured at 1 rad/s
    assert wait_for(lambda: abs(client.last_telemetry.omega_rad_s[0] - 1.0) < 0.05)


def test_refused_setpoint_busy_and_parameters(board):
    device, client, _ = board
    with pytest.raises(wb.DeviceError) as err:
        client.set_speeds([0.0, 0.0, 0.0, 200.0])
    assert (err.value.name, err.value.detail) == ("SETPOINT_ABOVE_MAX", 3)
    assert device.targets == [0, 0, 0, 0]  # the whole message was refused
    client.set_speeds([5.0, 0.0, 0.0, 0.0])
    assert wait_for(lambda: device.enabled[0])
    with pytest.raises(wb.DeviceError, match="BUSY"):
        client.set_param("MODE", 1)
    assert client.set_param("ACCEL_RAD_S2", 400) == 400
    assert client.get_param("ACCEL_RAD_S2") == 400
    client.save_params()
    assert client.set_param("ACCEL_RAD_S2", 50) == 50
    client.stop_all()
    assert wait_for(lambda: not any(device.enabled))
    client.load_defaults()
    assert client.get_param("ACCEL_RAD_S2") == 100
    device.reset()  # the saved image (400) comes back at boot
    assert wait_for(lambda: device.boots == 2)
    assert client.get_param("ACCEL_RAD_S2") == 400


def test_corrupt_frames_both_ways_are_counted(board):
    device, client, _ = board
    device.faults.corrupt_next(60)
    assert wait_for(lambda: sum(client.decoder.dropped.values()) >= 1)
    seq_before = client.last_telemetry.seq
    assert wait_for(lambda: client.last_telemetry.seq > seq_before + 10)  # it resynchronised
    junk = os.open(device.slave_path, os.O_WRONLY | os.O_NOCTTY)
    try:
        mangled = bytearray(wp.encode("HEARTBEAT"))
        mangled[1] ^= 0x40
        os.write(junk, bytes(mangled) + b"\x01" * 60 + b"\x00")
    finally:
        os.close(junk)
    assert wait_for(lambda: device.stats["oversize"] == 1)
    stats = client.stats()
    assert (stats["bad_crc"], stats["oversize"]) == (1, 1)


def test_receiver_rules_reply_like_the_firmware():
    with WheelBoardEmulator() as device:
        host = os.open(device.slave_path, os.O_RDWR | os.O_NOCTTY)
        decoder = wp.FrameDecoder()
        try:
            device.handle_rx(wp.encode_raw(0x03, b"\x00" * 3), 0.0)  # SET_SPEEDS, 3 bytes
            device.handle_rx(wp.encode_raw(0x82, b"\x00" * 33), 0.0)  # a device-to-host id
            device.handle_rx(wp.encode_raw(0x42, b""), 0.0)  # not in the table
            device.handle_rx(wp.encode("PARAM_GET", param_id=len(wp.PARAMS)), 0.0)
            device.handle_rx(wp.encode("PARAM_SET", param_id=9, value=5), 0.0)  # below 20 ms
            time.sleep(0.05)
            replies = decoder.feed(os.read(host, 4096))
        finally:
            os.close(host)
    errors = [(wp.BY_ID[m.fields["req_id"]].name if m.fields["req_id"] in wp.BY_ID else
               m.fields["req_id"], wp.error_name(m.fields["code"]), m.fields["detail"])
              for m in replies]  # fmt: skip
    assert errors == [
        ("SET_SPEEDS", "BAD_LENGTH", 3),
        ("TELEMETRY", "UNKNOWN_MESSAGE", 0x82),
        (0x42, "UNKNOWN_MESSAGE", 0x42),
        ("PARAM_GET", "UNKNOWN_PARAM", len(wp.PARAMS)),
        ("PARAM_SET", "PARAM_OUT_OF_RANGE", 9),
    ]
    assert device.stats["bad_length"] == 1 and device.stats["unknown_id"] == 2


def test_reset_is_seen_as_a_restarted_sequence_and_watchdog_fault(board):
    device, client, events = board
    client.set_speeds([30.0, 0.0, 0.0, 0.0])
    assert wait_for(lambda: client.last_telemetry.omega_rad_s[0] > 29.9)
    before = client.last_telemetry
    device.reset(down_s=0.2, watchdog=True)
    assert events.get(timeout=2.0) == ["WATCHDOG_RESET"]
    after = client.last_telemetry
    assert after.seq < before.seq and after.t_us < before.t_us  # the board rebooted
    assert device.targets == [0, 0, 0, 0]
    # Outputs off: the wheel coasts (5 s time constant), it does not stop at once.
    assert 20.0 < device.wheel_speeds_rad_s()[0] < 30.0
    assert client.hello is not None and client.connect()["proto_version"] == wp.PROTO_VERSION


def test_frames_sent_while_the_emulator_was_held_up_keep_their_time():
    """Polled on its own clock: heartbeats sent every 50 ms while the emulator was held up for
    0.6 s (a loaded CPU) keep it alive, as they would keep the board; the timer then runs from the
    last of them. A lone heartbeat after a held-up 0.6 s ends a silence the board did see."""
    beats = wp.encode("HEARTBEAT") * 12  # 0.6 s of the driver's 50 ms beat
    # HEARTBEAT_MS 250 from the last beat, taken at 0.61 s: still alive at 0.85 s, lost at 0.87
    assert _faults_held_up(beats, [0.61, 0.85, 0.87]) == [[], [], ["HEARTBEAT_LOST"]]
    assert _faults_held_up(wp.encode("HEARTBEAT"), [0.61]) == [["HEARTBEAT_LOST"]]
    assert _faults_held_up(b"", [0.25, 0.27]) == [[], ["HEARTBEAT_LOST"]]  # from the 10 ms beat


def _faults_held_up(frames: bytes, polls_s: list[float]) -> list[list[str]]:
    """An emulator polled at 0 s (boot), at 10 ms after the driver's first heartbeat, then at
    each of ``polls_s``, ``frames`` sent before the first of those: its latched faults after
    each."""
    with WheelBoardEmulator() as dev:
        host = os.open(dev.slave_path, os.O_WRONLY | os.O_NOCTTY)
        try:
            dev.poll(now_s=0.0)
            for sent, now_s in ((wp.encode("HEARTBEAT"), 0.01), (frames, polls_s[0])):
                os.write(host, sent)
                _until_pending(dev, len(sent))
                dev.poll(now_s=now_s)
            faults = [wp.fault_names(dev.fault_word)]
            for now_s in polls_s[1:]:
                dev.poll(now_s=now_s)
                faults.append(wp.fault_names(dev.fault_word))
            return faults
        finally:
            os.close(host)


def _until_pending(dev: WheelBoardEmulator, n_bytes: int) -> None:
    """Wait until the pty holds ``n_bytes`` for the emulator (the kernel passes them on later
    than the write returns)."""
    count = array.array("i", [0])
    deadline = time.monotonic() + 2.0
    while time.monotonic() < deadline:
        fcntl.ioctl(dev.link.fileno(), termios.FIONREAD, count)
        if count[0] >= n_bytes:
            return
        time.sleep(0.001)
    raise AssertionError(f"the pty holds {count[0]} of {n_bytes} bytes")


def test_ripple_and_lag_on_the_emulator_clock():
    """Driven tick by tick on its own clock (no thread): ramp, lag, then a 5 % ripple."""
    emu = WheelEmuConfig(time_constant_s=0.02, ripple_fraction=0.05, speed_error_std_rad_s=0.0)
    dev, trace = _spun_up(emu, 20000, 1500)
    # a frame every other tick, the 750th still on the wire (38 bytes at 1 Mbaud)
    assert dev.ticks == 1500 and dev.telemetry_sent == 749
    # 0.1 s of ramp at 100 rad/s^2: setpoint 10 rad/s, the 20 ms lag 100 x 0.02 = 2 rad/s behind
    assert trace[99] == pytest.approx(8.0, abs=0.5)  # (+-5 % ripple)
    steady = np.array(trace[500:])  # ramp done at 0.2 s, lag settled well before 0.5 s
    assert steady.max() == pytest.approx(21.0, abs=0.05)
    assert steady.min() == pytest.approx(19.0, abs=0.05)


def test_the_speed_loop_error_is_gauss_markov_at_the_motor_time_constant():
    """At a held setpoint the true speed errs by the closed-form first-order Gauss-Markov
    process: stationary std ``speed_error_std_rad_s``, correlation exp(-lag / time constant)."""
    emu = WheelEmuConfig(time_constant_s=0.05, speed_error_std_rad_s=0.02, seed=7)
    _, trace = _spun_up(emu, 50000, 50000)
    error = np.array(trace[1000:]) - 50.0  # the ramp (0.5 s) and five lags done
    assert np.std(error) == pytest.approx(0.02, rel=0.1)  # about 1000 time constants
    for lag_ticks in (10, 50, 100):
        rho = np.corrcoef(error[:-lag_ticks], error[lag_ticks:])[0, 1]
        assert rho == pytest.approx(np.exp(-lag_ticks * 1e-3 / 0.05), abs=0.05)
    _, exact = _spun_up(replace(emu, speed_error_std_rad_s=0.0), 50000, 2000)
    assert np.all(np.array(exact[1000:]) == pytest.approx(50.0, abs=1e-3))  # the lag alone


def test_a_setpoint_acts_from_the_tick_after_its_frame_and_telemetry_crosses_the_wire():
    """As the firmware: a tick reads the encoder of the wheel turned under the last tick's
    drive, then ramps the setpoint; the telemetry of a tick leaves when its bits have crossed
    the wire; a truth step ending between ticks sees the wheel carried on by its lag."""
    emu = WheelEmuConfig(time_constant_s=0.05, speed_error_std_rad_s=0.0)
    with WheelBoardEmulator(emu, baud=1_000_000) as dev:
        dev.tick(0.0)
        speeds = dict.fromkeys(("w0_mrad_s", "w1_mrad_s", "w2_mrad_s", "w3_mrad_s"), 0)
        dev.handle_rx(wp.encode("SET_SPEEDS", **(speeds | {"w0_mrad_s": 10000})), 0.0005)
        dev.tick(0.001)  # the frame's tick: the setpoint ramps, the wheel has not moved yet
        assert dev.wheel_speeds_rad_s()[0] == 0.0 and dev.setpoints[0] == 100
        dev.tick(0.002)  # one tick under 0.1 rad/s: the lag's exact step
        expected = 0.1 * (1.0 - math.exp(-0.001 / 0.05))
        assert dev.wheel_speeds_rad_s()[0] == pytest.approx(expected, rel=1e-12)
        halfway = dev.wheel_speeds_rad_s(at_s=0.0025)[0]
        assert expected < halfway < dev.setpoints[0] / 1000.0
        assert dev.telemetry_sent == 0  # tick 2's frame is still on the wire
        assert dev.next_send_s == pytest.approx(0.002 + wp.wire_time_s("TELEMETRY", 1_000_000))
        dev.tick(dev.next_send_s)
        assert dev.telemetry_sent == 1


def test_a_reply_leaves_behind_the_telemetry_on_the_wire():
    """One UART: a frame taken before a request reaches the host before its reply."""
    with WheelBoardEmulator(WheelEmuConfig()) as dev:
        fd = os.open(dev.slave_path, os.O_RDONLY | os.O_NONBLOCK)
        dev.tick(0.0)
        dev.tick(0.002)  # tick 2's telemetry on the wire
        dev.handle_rx(wp.encode("GET_STATS"), 0.0021)
        time.sleep(0.05)
        names = [m.name for m in wp.FrameDecoder().feed(os.read(fd, 4096))]
        os.close(fd)
        assert names == ["TELEMETRY", "STATS"]


def _spun_up(emu, w0_mrad_s, ticks):
    """An emulator on its own clock (no thread) with wheel 0 set to ``w0_mrad_s`` at 0, ticked
    ``ticks`` times: (the emulator, wheel 0's true speed after each tick, rad/s)."""
    with WheelBoardEmulator(emu) as dev:
        dev.tick(0.0)  # the board boots when first polled
        speeds = dict.fromkeys(("w0_mrad_s", "w1_mrad_s", "w2_mrad_s", "w3_mrad_s"), 0)
        dev.handle_rx(wp.encode("SET_SPEEDS", **(speeds | {"w0_mrad_s": w0_mrad_s})), 0.0)
        trace = []
        for k in range(1, ticks + 1):
            if k % 100 == 0:  # the host's control loop
                dev.handle_rx(wp.encode("HEARTBEAT"), k * 1e-3)
            dev.tick(k * 1e-3)
            trace.append(dev.wheel_speeds_rad_s()[0])
    return dev, trace


def test_gyrotens_wheels_calibrate_reports_and_clears_the_boot_fault_then_saves(capsys):
    """The command against the emulated board: the boot's HEARTBEAT_LOST printed before it is
    cleared, one line per calibrated wheel, then the save (the emulated board is calibrated: its
    offsets stay 0)."""
    from gyrohost.cli import main

    device = WheelBoardEmulator().start()
    try:
        time.sleep(0.4)  # no host yet: HEARTBEAT_LOST latches after HEARTBEAT_MS (250 ms)
        argv = ["wheels", "calibrate", "--port", device.slave_path, "--wheel", "1", "--wheel", "3"]
        assert main(argv) == 0
    finally:
        device.close()
    out, err = capsys.readouterr()
    assert (err + out).splitlines() == [
        "wheel board: HEARTBEAT_LOST latched at connect: " + wp.FAULTS[0][1],
        "wheel board: cleared HEARTBEAT_LOST",
        "wheel 1: calibrating (it turns back and forth by one electrical turn)",
        "wheel 1: ENC_OFFSET_M1 = 0 (0.0 deg)",
        "wheel 3: calibrating (it turns back and forth by one electrical turn)",
        "wheel 3: ENC_OFFSET_M3 = 0 (0.0 deg)",
        "saved to EEPROM",
    ]
