"""Firmware in the loop: the watchdog, the parameters at boot and the host link at its line rate.

The client here is raw (frames from :mod:`gyrohost.drivers.wheelproto` on the pty, a reader
thread decoding the replies), so that the test controls every byte and its timing. The harness
delivers the bytes at the real line rate (1 Mbaud, one byte per 10 us of simulated time) and acts
as the stock bootloader on a reset (MCUSR cleared); its ``RESET``, ``RXMARK`` and ``STATS`` lines
carry simulated times. Every time bound below is in simulated time, never wall time.
"""

from __future__ import annotations

import queue
import threading
import time

import pytest
import serial
from filharness import Harness, HarnessError, firmware_elf, parse_kv, set_offsets, stats_rpm

from gyrohost.drivers import wheelproto as wp

pytestmark = pytest.mark.fil

WATCHDOG_RESET = wp.fault_mask(["WATCHDOG_RESET"])
ALL_FAULTS = wp.fault_mask([name for name, _ in wp.FAULTS.values()])
OUTPUTS_ENABLED = 1 << 0
SPEED_MRAD_S = [75000, -75000, 75000, -75000]  # about 716 rpm
WAIT_S = 20.0  # wall-clock limit of every wait: generous for a loaded 2-core host
STATS_PERIOD_S = 0.0005
# Tick to PWM under the flood, from docs/hardware.md#link-load: a step waits for the rest of the
# longest job of the main loop (1,105 cycles), then runs the step (2,658) and the PWM update (131),
# all stretched by the receive interrupt (160 / 103); plus the tick interrupt and the loop's test
# (85), a receive interrupt in progress at the tick (72) and STOP_ALL's five matched bytes (15 more
# each): 6,281 cycles, 392 us. step_max_us counts Timer2 from its clear, never above it.
STEP_BOUND_US = 392


def wire(name: str, **fields: int) -> bytes:
    """A frame as the host sends it: a leading 0x00 (ends any fragment before it) and the frame."""
    return b"\x00" + wp.encode(name, **fields)


class Link:
    """The board's pty with a reader thread; ``send`` writes whole frames (leading 0x00)."""

    def __init__(self, port: str) -> None:
        self.ser = serial.Serial(port, timeout=0.02)
        self.messages: queue.Queue[wp.Message] = queue.Queue()
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        decoder = wp.FrameDecoder()
        while not self._stop.is_set():
            for msg in decoder.feed(self.ser.read(4096)):
                self.messages.put(msg)

    def write(self, data: bytes) -> None:
        with self._lock:
            self.ser.write(data)

    def send(self, name: str, **fields: int) -> None:
        self.write(wire(name, **fields))

    def wait(self, ok, what: str) -> wp.Message:
        """The next message for which ``ok(msg)`` holds (the ones before it are dropped)."""
        deadline = time.monotonic() + WAIT_S
        while time.monotonic() < deadline:
            try:
                msg = self.messages.get(timeout=0.05)
            except queue.Empty:
                continue
            assert msg.name != "ERROR", f"device error while waiting for {what}: {msg.fields}"
            if ok(msg):
                return msg
        raise AssertionError(f"no {what} within {WAIT_S} s")

    def request(self, name: str, reply: str, **fields: int) -> wp.Message:
        self.send(name, **fields)
        return self.wait(lambda m: m.name == reply, f"{reply} to {name}")

    def set_param(self, name: str, value: int) -> None:
        pid = wp.PARAM_BY_NAME[name].id
        self.send("PARAM_SET", param_id=pid, value=value)
        self.wait(lambda m: m.name == "PARAM_VALUE" and m.fields["param_id"] == pid, name)

    def close(self) -> None:
        self._stop.set()
        self._reader.join(timeout=1.0)
        self.ser.close()


def telemetry(link: Link, ok=lambda m: True, what: str = "telemetry") -> dict:
    return link.wait(lambda m: m.name == "TELEMETRY" and ok(m), what).fields


def spin_up(h: Harness, link: Link, beat: threading.Event) -> None:
    """Offsets set (the EEPROM of the run is blank), faults cleared, four wheels at 716 rpm.

    ``beat`` is set while a heartbeat thread keeps the link alive. It beats before the faults are
    cleared: CLEAR_FAULTS does not restart the heartbeat count, so on a slow host a count that ran
    out during the set-up would latch HEARTBEAT_LOST again and the SET_SPEEDS would be refused.
    """
    beat.set()
    set_offsets(link)
    link.request("CLEAR_FAULTS", "ACK", mask=ALL_FAULTS)
    fields = {f"w{i}_mrad_s": v for i, v in enumerate(SPEED_MRAD_S)}
    link.send("SET_SPEEDS", **fields)
    deadline = time.monotonic() + WAIT_S
    while not all(abs(abs(r) - 716) < 15 for r in stats_rpm(h.latest_stats(timeout_s=WAIT_S))):
        assert time.monotonic() < deadline, f"wheels not at speed: {h.tail(2)}"


def heartbeat(link: Link, beat: threading.Event, done: threading.Event) -> None:
    while not done.wait(0.02):
        if beat.is_set():
            link.send("HEARTBEAT")


def harness_line(h: Harness, prefix: str) -> dict[str, str]:
    """The first logged harness line starting with ``prefix``, parsed; waits for it."""
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        for line in list(h.log):
            if line.startswith(prefix):
                return parse_kv(line)
        time.sleep(0.02)
    raise HarnessError(f"no {prefix!r} line; output:\n" + h.tail())


@pytest.fixture
def beat_link():
    """A factory of (harness, link, beat event) with a heartbeat thread; all closed at the end."""
    made = []
    done = threading.Event()

    def make(args: list[str]):
        h = Harness(firmware_elf(), args)
        link = Link(h.pty)
        beat = threading.Event()
        threading.Thread(target=heartbeat, args=(link, beat, done), daemon=True).start()
        made.append((h, link))
        return h, link, beat

    yield make
    done.set()
    for h, link in made:
        link.close()
        h.stop()


def hang_and_reset(
    h: Harness, link: Link, beat: threading.Event, command: str, wdrf: str = "1"
) -> dict:
    """Four wheels running, then ``command`` (a harness hang: the watchdog's reset follows, or a
    brown-out).
    Returns the harness's RESET line with ``dt_s``, the simulated time from the hang to it."""
    boot = telemetry(link)
    assert not boot["faults"] & WATCHDOG_RESET, boot
    spin_up(h, link, beat)
    running = telemetry(link, lambda m: m.fields["status"] & OUTPUTS_ENABLED, "outputs enabled")
    t_hang_s = float(parse_kv(h.command(command))["t_s"])
    reset = harness_line(h, "RESET ")
    assert reset["wdrf"] == wdrf, reset  # the watchdog's reset, as the chip flags it
    reset["dt_s"] = float(reset["t_s"]) - t_hang_s
    reset["t_us_before"] = running["t_us"]
    return reset


def outputs_off_after_reset(h: Harness, link: Link, reset: dict) -> dict:
    """Telemetry of the new boot (its clock restarted; the first frame may be lost, joined to
    the one the reset cut): every output off."""
    before = reset["t_us_before"]
    after = telemetry(link, lambda m: m.fields["t_us"] < before, "telemetry after the reset")
    assert not after["status"] & OUTPUTS_ENABLED, after
    pwm = h.command("pwm")
    assert all(f"m{i}=0/" in pwm for i in range(4)), pwm
    return after


@pytest.mark.parametrize("command", ["hang-cli", "tick-stop"])
def test_a_hang_no_interrupt_sees_resets_within_32_ms_with_every_output_off(beat_link, command):
    """A hang with interrupts disabled, or with Timer2 stopped (no tick interrupt either): only
    the watchdog, in plain reset mode, acts. It resets the chip 16 ms after the last step's kick
    (the hang comes up to one tick after it): the issue's limit is 32 ms. The harness clears
    MCUSR as the stock bootloader does and no interrupt could leave the mark, so the cause is
    lost (docs/hardware.md): no WATCHDOG_RESET. After the reset every output is off."""
    h, link, beat = beat_link([])
    reset = hang_and_reset(h, link, beat, command)
    assert 0.014 <= reset["dt_s"] <= 0.032, reset
    after = outputs_off_after_reset(h, link, reset)
    assert not after["faults"] & WATCHDOG_RESET, after


def test_without_the_bootloader_mcusr_reports_the_watchdog_reset(beat_link):
    """A board without the stk500v2 bootloader keeps MCUSR: WDRF reports even a hang with
    interrupts off; CLEAR_FAULTS clears it for good."""
    h, link, beat = beat_link(["--no-bootloader"])
    reset = hang_and_reset(h, link, beat, "hang-cli")
    assert reset["dt_s"] <= 0.032, reset
    after = outputs_off_after_reset(h, link, reset)
    assert after["faults"] & WATCHDOG_RESET, after
    link.request("CLEAR_FAULTS", "ACK", mask=WATCHDOG_RESET)
    later = telemetry(link, lambda m: not m.fields["faults"] & WATCHDOG_RESET, "cleared faults")
    assert later["t_us"] >= after["t_us"]


def test_a_hang_with_interrupts_on_is_marked_and_reported(beat_link):
    """A main loop hung with interrupts on: the tick interrupt finds BOARD_HANG_TICKS (8) ticks
    without a step, switches every output off and leaves the .noinit mark, which survives the
    stock bootloader: the next boot reports WATCHDOG_RESET. The reset comes from the watchdog,
    16 ms after the last kick."""
    h, link, beat = beat_link([])
    reset = hang_and_reset(h, link, beat, "hang")
    assert 0.014 <= reset["dt_s"] <= 0.032, reset
    after = outputs_off_after_reset(h, link, reset)
    assert after["faults"] & WATCHDOG_RESET, after


def test_a_brown_out_reset_is_reported_where_mcusr_survives(beat_link):
    """The brown-out detector's reset (BORF set) on a board without the stk500v2 bootloader:
    BROWN_OUT_RESET in the next boot's fault word, every output off. Behind the stock bootloader
    MCUSR is cleared and the cause is lost (docs/hardware.md)."""
    h, link, beat = beat_link(["--no-bootloader"])
    reset = hang_and_reset(h, link, beat, "brown-out", wdrf="0")
    assert reset["borf"] == "1", reset
    after = outputs_off_after_reset(h, link, reset)
    assert after["faults"] & wp.fault_mask(["BROWN_OUT_RESET"]), after
    assert not after["faults"] & WATCHDOG_RESET, after


def eeprom_image(**values: int) -> bytes:
    """An EEPROM with one parameter image in slot 0 (layout 3, docs/protocol.md), written by hand:
    the defaults with ``values`` on top, CRC good; slot 1 blank."""
    body = b"GW" + bytes([3, len(wp.PARAMS)]) + (1).to_bytes(2, "little")
    for spec in wp.PARAMS:
        body += values.get(spec.name, spec.default).to_bytes(4, "little", signed=True)
    image = body + wp.crc16(body).to_bytes(2, "little")
    return image + b"\xff" * (256 - len(image))


DISARMING = {  # a value past each fail-safe bound (docs/hardware.md), as the issue measured
    "HEARTBEAT_MS": 60000,
    "DECEL_RAD_S2": 1,
    "STALL_SPEED_MRAD_S": 0,
    "MOTION_FAULT_MS": 5000,
    "RUNAWAY_MARGIN_MRAD_S": 400000,
}


@pytest.mark.parametrize("value", [60000, 1000])
def test_an_eeprom_image_with_a_disarming_value_is_rejected_at_boot(beat_link, tmp_path, value):
    """A hand-made image whose CRC is good but whose HEARTBEAT_MS is 60 s: the boot loads the
    defaults and reports PARAMS_DEFAULTED; the same image with 1000 ms loads (KP 77 shows it)."""
    path = tmp_path / "eeprom.bin"
    path.write_bytes(eeprom_image(HEARTBEAT_MS=value, KP=77))
    h, link, _ = beat_link(["--eeprom", str(path)])
    boot = telemetry(link)
    loaded = value <= wp.PARAM_BY_NAME["HEARTBEAT_MS"].max
    defaulted = wp.fault_mask(["PARAMS_DEFAULTED"])
    assert bool(boot["faults"] & defaulted) != loaded, boot
    kp = link.request("PARAM_GET", "PARAM_VALUE", param_id=wp.PARAM_BY_NAME["KP"].id)
    assert kp.fields["value"] == (77 if loaded else wp.PARAM_BY_NAME["KP"].default)
    beat = link.request("PARAM_GET", "PARAM_VALUE", param_id=wp.PARAM_BY_NAME["HEARTBEAT_MS"].id)
    assert beat.fields["value"] == (value if loaded else 250)


def test_each_disarming_param_set_is_refused(beat_link):
    h, link, _ = beat_link([])
    for name, value in DISARMING.items():
        pid = wp.PARAM_BY_NAME[name].id
        link.send("PARAM_SET", param_id=pid, value=value)
        deadline = time.monotonic() + WAIT_S
        while True:
            msg = link.messages.get(timeout=max(deadline - time.monotonic(), 0.01))
            if msg.name in ("ERROR", "PARAM_VALUE"):
                break
        assert msg.name == "ERROR", f"{name} = {value} accepted: {msg.fields}"
        assert (msg.fields["req_id"], msg.fields["detail"]) == (wp.BY_NAME["PARAM_SET"].id, pid)
        assert wp.error_name(msg.fields["code"]) == "PARAM_OUT_OF_RANGE"
        held = link.request("PARAM_GET", "PARAM_VALUE", param_id=pid).fields["value"]
        assert held == wp.PARAM_BY_NAME[name].default, name


def wait_sim(h: Harness, t_s: float) -> None:
    deadline = time.monotonic() + WAIT_S
    while h.sim_time_s() < t_s:
        assert time.monotonic() < deadline, f"simulation stuck before {t_s} s: {h.tail(2)}"
        time.sleep(0.01)


def burst_replies(link: Link) -> list[int]:
    """The values of the next 20 PARAM_VALUE replies (nothing else but telemetry before them)."""
    values = []
    while len(values) < 20:
        msg = link.wait(lambda m: m.name in ("PARAM_VALUE", "ACK"), "burst replies")
        assert msg.name == "PARAM_VALUE", f"{msg} before the 20 PARAM_VALUEs: {values}"
        values.append(msg.fields["value"])
    return values


def test_line_rate_burst_in_a_setpoint_stream_nothing_lost_stop_all_within_2_ms(beat_link):
    """The worst host traffic of docs/protocol.md at 1 Mbaud, generated by the harness in
    simulated time (so that no host scheduling bunches it): SET_SPEEDS every 1 ms and HEARTBEAT
    every 20 ms for 300 ms, a burst of 20 PARAM_SETs (220 bytes back to back) in the middle;
    then, the stream over, the burst again with STOP_ALL behind it.

    Every PARAM_SET is answered in order, the STOP_ALL acknowledged after them, no counter of
    lost or bad frames moves, the UART never overruns (harness rx_overrun), and the drive brakes
    within 2 ms and a step's delay of STOP_ALL's last byte (the harness's RXMARK), while the 220
    bytes before it are still being dispatched. The longest tick-to-PWM time (step_max_us, the
    chip's Timer2 count: simulated time) stays within STEP_BOUND_US, the bound
    docs/hardware.md#link-load derives from the main loop's jobs (a step waits for at most the
    rest of one job); where the burst falls against the tick varies from run to run (the harness
    queues it when its command arrives).
    """

    h, link, beat = beat_link(
        ["--rx-mark", wp.encode("STOP_ALL")[:-1].hex(), "--stats-period", f"{STATS_PERIOD_S:g}"]
    )
    telemetry(link)
    link.set_param("DECEL_RAD_S2", 10000)  # the setpoint drops 10 rad/s in the first stop tick
    spin_up(h, link, beat)

    speeds = {f"w{i}_mrad_s": v for i, v in enumerate(SPEED_MRAD_S)}
    accel = wp.PARAM_BY_NAME["ACCEL_RAD_S2"].id

    def burst(first: int) -> bytes:
        return b"".join(wire("PARAM_SET", param_id=accel, value=first + k) for k in range(20))

    t0 = h.sim_time_s()
    h.command("rx-every 1000 300 " + wire("SET_SPEEDS", **speeds).hex())
    h.command("rx-every 20000 15 " + wire("HEARTBEAT").hex())
    wait_sim(h, t0 + 0.1)
    h.command("rx " + burst(101).hex())
    assert burst_replies(link) == [101 + k for k in range(20)]
    wait_sim(h, t0 + 0.35)  # the stream is over

    h.command("rx " + (burst(201) + wire("STOP_ALL")).hex())
    assert burst_replies(link) == [201 + k for k in range(20)]
    link.wait(lambda m: m.name == "ACK" and m.fields["req_id"] == wp.BY_NAME["STOP_ALL"].id, "ACK")
    t_mark_s = int(harness_line(h, "RXMARK ")["t_us"]) * 1e-6

    stats = link.request("GET_STATS", "STATS").fields
    lost = {k: v for k, v in stats.items() if k != "step_max_us" and v}
    assert not lost, stats
    assert stats["step_max_us"] <= STEP_BOUND_US, stats
    assert h.latest_stats()["rx_overrun"] == "0"

    # wheel 0's applied q voltage: its mean over the 20 ms before the mark, then the first sample
    # after the mark that is 0.1 V lower (the drive slews 1000 q15, about 0.2 V, in its first
    # braking step); the STATS lines sample it every STATS_PERIOD_S
    samples = [(float(s["t_s"]), float(s["vq"].split(",")[0])) for s in list(h.stats)]
    before = [v for t, v in samples if t_mark_s - 0.02 <= t < t_mark_s]
    steady = sum(before) / len(before)
    braking = [t for t, v in samples if t >= t_mark_s and v < steady - 0.1]
    assert braking, f"no braking after the mark at {t_mark_s} s: {samples[-5:]}"
    latency_s = braking[0] - t_mark_s
    # noted in the tick after the last byte, braked by the next tick's step: 2 ms, plus how much
    # later that step's PWM update comes than the first's (at most STEP_BOUND_US), plus the
    # sampling
    bound_s = 0.002 + STEP_BOUND_US * 1e-6 + STATS_PERIOD_S
    assert latency_s <= bound_s, f"drive braked {latency_s * 1e3:.3f} ms after"
    step_cycles = max(int(s["cyc_max"]) for s in h.stats)  # the step's cycles, ISRs included
    print(f"STOP_ALL: braking {latency_s * 1e3:.3f} ms after its last byte; {stats}")
    print(f"control step under the bursts: at most {step_cycles} cycles")
