"""Wheel-board client against hand-built byte streams and a fake board on os.openpty()."""

import os
import queue
import select
import struct
import threading
import time
import tty

import pytest
from protocol_reference import crc_bytewise

from gyrohost.drivers import wheelboard as wb
from gyrohost.drivers import wheelproto as wp


def cobs_by_hand(raw: bytes) -> bytes:
    out, code_pos, code = bytearray([0]), 0, 1
    for b in raw:
        if b == 0:
            out[code_pos] = code
            code_pos, code = len(out), 1
            out.append(0)
        else:
            out.append(b)
            code += 1
    out[code_pos] = code
    return bytes(out)


def telemetry_bytes(seq: int, mrad: tuple[int, int, int, int], faults: int = 0) -> bytes:
    body = bytes([0x82]) + struct.pack(
        "<IH4i4hBH", 1000 * seq, seq, *mrad, 100, -100, 0, 0, 1, faults
    )
    return cobs_by_hand(body + struct.pack("<H", crc_bytewise(body))) + b"\x00"


class BytesPort:
    """A serial-like object replaying a byte stream in small chunks."""

    def __init__(self, data: bytes):
        self.data, self.written = bytearray(data), bytearray()

    @property
    def in_waiting(self) -> int:
        return min(len(self.data), 7)

    def read(self, n: int) -> bytes:
        if not self.data:
            time.sleep(0.005)
            return b""
        chunk = bytes(self.data[:7])
        del self.data[:7]
        return chunk

    def write(self, data: bytes) -> int:
        self.written += data
        return len(data)


def test_hand_built_stream_with_garbage_and_corrupt_frames():
    good = [telemetry_bytes(i, (74870, -74870, 0, i)) for i in range(5)]
    bad_crc = bytearray(telemetry_bytes(9, (1, 2, 3, 4)))
    bad_crc[5] ^= 0x01
    stream = b"\x13\x37garbage\x00" + good[0] + good[1] + bytes(bad_crc) + good[2] + b"\x00\x00"
    stream += good[3] + b"\xaa" * 80 + b"\x00" + good[4]
    got = []
    board = wb.WheelBoard(BytesPort(stream), on_telemetry=got.append)
    deadline = time.monotonic() + 2
    while len(got) < 5 and time.monotonic() < deadline:
        time.sleep(0.01)
    board.close()
    assert [t.seq for t in got] == [0, 1, 2, 3, 4]
    assert got[0].omega_rad_s == pytest.approx((74.87, -74.87, 0.0, 0.0))
    assert got[0].drive[0] == pytest.approx(100 / 32767)
    # The leading garbage claims a 19-byte block in 9 bytes: bad COBS.
    assert board.decoder.dropped == {"bad_cobs": 1, "bad_crc": 1, "oversize": 1}
    assert board.telemetry.qsize() == 5


class FakeBoard(threading.Thread):
    """Answers like the firmware's dispatcher on the master side of a pseudo-terminal."""

    def __init__(
        self,
        proto_version: int = wp.PROTO_VERSION,
        silent: bool = False,
        boot_s: float = 0.0,
        stats_delay_s: float = 0.0,
    ):
        super().__init__(daemon=True)
        self.stats_delay_s = stats_delay_s  # a STATS reply takes this long (a slow link)
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        self._slave = slave
        self.proto_version, self.silent = proto_version, silent
        self.awake_at = time.monotonic() + boot_s  # a bootloader ignores frames until then
        self.params = {p.id: p.default for p in wp.PARAMS}
        self.speeds = [0, 0, 0, 0]
        self.cleared: list[int] = []  # CLEAR_FAULTS masks received
        self.heartbeats: list[float] = []
        self.received: list[str] = []
        self.stop = threading.Event()
        self.start()

    def send(self, name: str, **fields: int) -> None:
        os.write(self.master, wp.encode(name, **fields))

    def send_telemetry(self, seq: int, faults: int = 0) -> None:
        os.write(self.master, telemetry_bytes(seq, (1000, 2000, 3000, 4000), faults))

    def run(self) -> None:
        dec = wp.FrameDecoder()
        while not self.stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.02)
            if not ready:
                continue
            try:
                data = os.read(self.master, 256)
            except OSError:
                return
            for msg in dec.feed(data):
                self.received.append(msg.name)
                if not self.silent and time.monotonic() >= self.awake_at:
                    self.handle(msg)

    def handle(self, msg: wp.Message) -> None:
        f = msg.fields
        if msg.name == "HELLO":
            self.send(
                "HELLO_REPLY",
                proto_version=self.proto_version,
                fw_major=1,
                fw_minor=0,
                n_wheels=4,
                n_params=len(wp.PARAMS),
                tick_hz=1000,
            )
        elif msg.name == "HEARTBEAT":
            self.heartbeats.append(time.monotonic())
        elif msg.name == "SET_SPEEDS":
            vmax = self.params[wp.PARAM_BY_NAME["SPEED_MAX_MRAD_S"].id]
            sp = [f[f"w{i}_mrad_s"] for i in range(4)]
            bad = [i for i, v in enumerate(sp) if abs(v) > vmax]
            if bad:
                self.send("ERROR", req_id=msg.id, code=3, detail=bad[0])
            else:
                self.speeds = sp
        elif msg.name == "CLEAR_FAULTS":
            self.cleared.append(f["mask"])
            self.send("ACK", req_id=msg.id)
        elif msg.name == "CALIBRATE_ENC":  # wheel 3 counts backwards: REVERSED
            if f["wheel"] == 3:
                self.send("ERROR", req_id=msg.id, code=9, detail=3)
            else:
                self.params[wp.PARAM_BY_NAME[f"ENC_OFFSET_M{f['wheel']}"].id] = 1000 + f["wheel"]
                self.send("ACK", req_id=msg.id)
        elif msg.name in ("STOP_ALL", "PARAM_SAVE", "PARAM_DEFAULTS"):
            self.send("ACK", req_id=msg.id)
        elif msg.name == "PARAM_GET":
            self.send("PARAM_VALUE", param_id=f["param_id"], value=self.params[f["param_id"]])
        elif msg.name == "PARAM_SET":
            if f["param_id"] == wp.PARAM_BY_NAME["MODE"].id and any(self.speeds):
                self.send("ERROR", req_id=msg.id, code=7, detail=f["param_id"])
                return
            self.params[f["param_id"]] = f["value"]
            self.send("PARAM_VALUE", param_id=f["param_id"], value=f["value"])
        elif msg.name == "GET_STATS":
            time.sleep(self.stats_delay_s)
            self.send("STATS", **dict.fromkeys(wp.BY_NAME["STATS"].fields, 0))

    def close(self) -> None:
        self.stop.set()
        self.join(1)
        os.close(self.master)
        os.close(self._slave)


@pytest.fixture
def fake():
    board = FakeBoard()
    yield board
    board.close()


def test_handshake_and_commands(fake):
    with wb.WheelBoard(fake.path) as board:
        assert board.hello["fw_major"] == 1
        board.set_speeds([74.87, -74.87, 0.0, 1.0])
        assert fake.speeds == [74870, -74870, 0, 1000]
        assert board.set_param("HEARTBEAT_MS", 120) == 120
        assert board.get_param("HEARTBEAT_MS") == 120
        board.save_params()
        board.stop_all()
        assert board.stats()["bad_crc"] == 0
    assert fake.received[-1] == "STOP_ALL"  # close() leaves the wheels ramping down


def test_refused_setpoint_raises_named_device_error(fake):
    with wb.WheelBoard(fake.path) as board:
        with pytest.raises(wb.DeviceError) as err:
            board.set_speeds([0.0, 0.0, 500.0, 0.0])
        assert err.value.name == "SETPOINT_ABOVE_MAX"
        assert err.value.detail == 2
        assert "SET_SPEEDS refused" in str(err.value)
        assert isinstance(err.value, RuntimeError)
        board.set_speeds([1.0, 0, 0, 0])
        with pytest.raises(wb.DeviceError, match="BUSY"):
            board.set_param("MODE", 1)


def test_a_refusal_is_raised_by_the_call_it_refuses_when_replies_come_late():
    """A refused SET_SPEEDS still gets the STATS of its confirming GET_STATS, 0.2 s after the
    refusal: the call takes it before it raises, so the next calls pair with their own replies
    (the next refusal is raised by its own call, not one call later)."""
    board_sim = FakeBoard(stats_delay_s=0.2)
    try:
        with wb.WheelBoard(board_sim.path) as board:
            with pytest.raises(wb.DeviceError, match="SETPOINT_ABOVE_MAX"):
                board.set_speeds([500.0, 0.0, 0.0, 0.0])
            board.set_speeds([1.0, 0.0, 0.0, 0.0])
            with pytest.raises(wb.DeviceError) as err:
                board.set_speeds([0.0, 0.0, 500.0, 0.0])
            assert err.value.detail == 2
    finally:
        board_sim.close()


def test_host_side_checks_before_sending(fake):
    with wb.WheelBoard(fake.path) as board:
        with pytest.raises(ValueError, match="wheel 1 speed nan"):
            board.set_speeds([0.0, float("nan"), 0.0, 0.0])
        with pytest.raises(ValueError, match="need 4 speeds"):
            board.set_speeds([0.0])
        with pytest.raises(ValueError, match="unknown wheel-board parameter 'KD'"):
            board.get_param("KD")
        with pytest.raises(ValueError, match=r"POLE_PAIRS: 0 outside \[1, 40\]"):
            board.set_param("POLE_PAIRS", 0)


def test_version_mismatch_refused_with_clear_message():
    fake = FakeBoard(proto_version=wp.PROTO_VERSION + 1)
    try:
        board = wb.WheelBoard(fake.path)
        with pytest.raises(
            wb.FirmwareMismatchError,
            match=rf"speaks protocol v{wp.PROTO_VERSION + 1}, this host speaks v{wp.PROTO_VERSION}",
        ):
            board.connect()
        board.close()
    finally:
        fake.close()


def test_silent_board_times_out_after_its_boot_window_of_hellos():
    fake = FakeBoard(silent=True)
    try:
        board = wb.WheelBoard(fake.path, reply_timeout_s=0.1, boot_window_s=0.35)
        with pytest.raises(wb.WheelBoardTimeout, match=r"no HELLO_REPLY .* within 0.35 s"):
            board.connect()
        board.close()
        assert fake.received.count("HELLO") >= 3  # one every 0.1 s
    finally:
        fake.close()


def test_a_board_in_its_bootloader_answers_a_later_hello():
    """Opening the port resets the Mega into its bootloader, which ignores frames for 1-2 s: the
    client repeats HELLO through the boot window (docs/protocol.md#boot-state)."""
    fake = FakeBoard(boot_s=0.6)
    try:
        with wb.WheelBoard(fake.path) as board:
            assert board.hello["proto_version"] == wp.PROTO_VERSION
        assert fake.received.count("HELLO") >= 2
    finally:
        fake.close()


def test_heartbeat_thread_runs_at_its_period(fake):
    with wb.WheelBoard(fake.path, heartbeat_period_s=0.02):
        time.sleep(0.5)
    beats = len(fake.heartbeats)
    assert 10 <= beats <= 30, beats


def test_background_heartbeat_only_while_no_wheel_is_commanded(fake):
    """A turning wheel lives only on the caller's frames: the driver's own thread beats while
    every commanded speed is zero, and heartbeat() sends at most one frame a period."""
    with wb.WheelBoard(fake.path, heartbeat_period_s=0.02) as board:
        time.sleep(0.2)
        assert len(fake.heartbeats) >= 5  # idle: the background thread beats
        board.set_speeds([1.0, 0.0, 0.0, 0.0])
        time.sleep(0.05)  # a beat already on its way lands
        driving = len(fake.heartbeats)
        time.sleep(0.3)
        assert len(fake.heartbeats) == driving
        board.heartbeat()
        board.heartbeat()  # within the period of the first: not sent
        time.sleep(0.1)
        assert len(fake.heartbeats) == driving + 1
        board.set_speeds([0.0, 0.0, 0.0, 0.0])
        time.sleep(0.2)
        assert len(fake.heartbeats) >= driving + 5  # idle again
        with pytest.raises(wb.DeviceError, match="SETPOINT_ABOVE_MAX"):
            board.set_speeds([1e3, 0.0, 0.0, 0.0])  # refused: nothing turns
        idle = len(fake.heartbeats)
        time.sleep(0.2)
        assert len(fake.heartbeats) >= idle + 5


def test_telemetry_queue_and_fault_events(fake):
    events: queue.Queue = queue.Queue()
    with wb.WheelBoard(fake.path, on_fault=events.put) as board:
        for seq in range(10):
            fake.send_telemetry(seq)
        fake.send_telemetry(10, faults=0b11)  # heartbeat lost + encoder 0
        assert events.get(timeout=1) == ["HEARTBEAT_LOST", "ENCODER_M0"]
        samples = [board.telemetry.get(timeout=1) for _ in range(11)]
        assert [s.seq for s in samples] == list(range(11))
        assert samples[0].omega_rad_s == pytest.approx((1.0, 2.0, 3.0, 4.0))
        with pytest.raises(wb.WheelFaultError, match="HEARTBEAT_LOST: no control frame"):
            board.check_faults()
        board.clear_faults(board.faults)
        board.check_faults()


def test_clear_faults_sends_only_the_named_bits(fake):
    with wb.WheelBoard(fake.path) as board:
        assert board.clear_faults([]) == []
        assert board.clear_faults(["HEARTBEAT_LOST", "ENC_DIAG", "HEARTBEAT_LOST"]) == [
            "HEARTBEAT_LOST",
            "ENC_DIAG",
        ]
        with pytest.raises(wp.ProtocolError, match="unknown wheel-board fault names"):
            board.clear_faults(["ENCODER_M9"])
        board.get_param("MODE")  # a round trip: every earlier frame has been handled
    assert fake.cleared == [1 | 1 << 10]


def test_calibrate_returns_the_offset_saves_and_names_a_failure(fake):
    with wb.WheelBoard(fake.path) as board:
        assert board.calibrate(2) == 1002
        # the idle heartbeat may follow it (the board's wheels stand still)
        assert [f for f in fake.received if f != "HEARTBEAT"][-1] == "PARAM_SAVE"
        with pytest.raises(
            wb.CalibrationError, match=r"wheel 3 failed: REVERSED \(the encoder counts down"
        ):
            board.calibrate(3)
        with pytest.raises(ValueError, match="wheel 4 is not one of 0..3"):
            board.calibrate(4)


def test_run_reports_each_latched_fault_before_clearing_only_those(fake):
    from gyrohost.bringup.wheel_faults import clear_reported_faults

    lines: list[str] = []
    latched = 1 << 0 | 1 << 6  # HEARTBEAT_LOST, PARAMS_DEFAULTED
    with wb.WheelBoard(fake.path) as board:
        threading.Timer(0.1, fake.send_telemetry, (0,), {"faults": latched}).start()
        cleared = clear_reported_faults(board, lines.append)
        # a fault latching after the report (RUNAWAY) is not in the mask: it stays latched
        fake.send_telemetry(1, faults=latched | 1 << 12)
        board.get_param("MODE")
    assert cleared == ["HEARTBEAT_LOST", "PARAMS_DEFAULTED"]
    assert fake.cleared == [latched]
    assert lines == [
        "wheel board: HEARTBEAT_LOST latched at connect: " + wp.FAULTS[0][1],
        "wheel board: PARAMS_DEFAULTED latched at connect: " + wp.FAULTS[6][1],
        "wheel board: cleared HEARTBEAT_LOST, PARAMS_DEFAULTED",
    ]
