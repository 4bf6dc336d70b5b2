"""The FIL harness itself, checked with its own tiny firmware (firmware/sim/selftest/selftest.c).

The self-test firmware steps each motor open loop (a rotating voltage vector) at a known speed
and prints the raw AS5048A words it reads every 10 ms. A synchronous machine driven that way must
turn at exactly field speed / pole pairs whatever the model's constants: that is the independent
reference the encoder readings and the harness's own rotor speed are checked against.
"""

from __future__ import annotations

import time

import pytest
import serial
from filharness import SELFTEST_ELF, Harness, stats_rpm

pytestmark = pytest.mark.fil

TARGET_RPM = [100.0, -100.0, 200.0, 0.0]  # selftest.c target_rpm[]
ENC_COUNTS = 16384


def parity_even(word: int) -> bool:
    return bin(word).count("1") % 2 == 0


def read_lines(port: serial.Serial, duration_s: float, want: int | None = None) -> list[str]:
    """Lines for ``duration_s`` of wall time, or until ``want`` lines (then the time is a limit)."""
    lines = []
    deadline = time.monotonic() + duration_s
    while time.monotonic() < deadline and (want is None or len(lines) < want):
        raw = port.readline()
        if raw:
            lines.append(raw.decode("ascii", errors="replace").strip())
    return lines


def angle_frames(lines: list[str]) -> list[tuple[int, list[int]]]:
    """``A <tick hex> <w0> .. <w3>`` lines -> (tick, raw words)."""
    frames = []
    for line in lines:
        parts = line.split()
        if len(parts) == 6 and parts[0] == "A":
            frames.append((int(parts[1], 16), [int(w, 16) for w in parts[2:]]))
    return frames


def mean_rpm(frames: list[tuple[int, list[int]]], motor: int) -> float:
    """Mean speed from unwrapped 14-bit angles; ticks are 1 ms of firmware time."""
    turns = 0
    prev = frames[0][1][motor] & 0x3FFF
    for _, words in frames[1:]:
        cur = words[motor] & 0x3FFF
        step = (cur - prev + ENC_COUNTS // 2) % ENC_COUNTS - ENC_COUNTS // 2
        turns += step
        prev = cur
    dt_s = (frames[-1][0] - frames[0][0]) * 1e-3
    return turns / ENC_COUNTS / dt_s * 60.0


@pytest.fixture(scope="module")
def selftest():
    with Harness(SELFTEST_ELF, ["--rate", "4"]) as h:
        port = serial.Serial(h.pty, 500000, timeout=0.2)
        yield h, port
        port.close()


def test_encoders_follow_open_loop_field(selftest):
    h, port = selftest
    while h.sim_time_s() < 2.0:  # past the 1 s speed ramp and its transient
        h.latest_stats()
    port.reset_input_buffer()  # may cut a line: the first one read is dropped
    frames = angle_frames(read_lines(port, 10.0, want=102)[1:])  # 1 simulated second
    assert len(frames) > 100, "no angle frames on the UART pty"
    for motor, target in enumerate(TARGET_RPM):
        for _, words in frames:
            assert parity_even(words[motor]), f"M{motor}: odd parity in {words[motor]:#06x}"
            assert not words[motor] & 0x4000, f"M{motor}: error flag in {words[motor]:#06x}"
        assert mean_rpm(frames, motor) == pytest.approx(target, abs=2.0), f"M{motor}"


def test_held_rotor_sits_at_commutation_zero(selftest):
    """M3 gets a fixed vector at sine phase 0: the rotor must hold at electrical angle 0 of the
    firmware convention (commut.h: elec = pole_pairs * encoder angle), the harness default."""
    _, port = selftest
    port.reset_input_buffer()
    frames = angle_frames(read_lines(port, 0.3))
    assert frames
    for _, words in frames:
        elec = (words[3] & 0x3FFF) * 7 % ENC_COUNTS
        assert min(elec, ENC_COUNTS - elec) < ENC_COUNTS // 36, f"{words[3]:#06x}"  # 10 deg


def test_harness_rotor_speed_matches_field(selftest):
    h, _ = selftest
    window = [h.latest_stats() for _ in range(4)]
    for motor, target in enumerate(TARGET_RPM):
        mean = sum(stats_rpm(s)[motor] for s in window) / len(window)
        assert mean == pytest.approx(target, abs=0.1 * abs(target) + 3.0), f"M{motor}"


def test_control_step_cycles_counted(selftest):
    h, _ = selftest
    s = h.latest_stats()
    assert int(s["steps"]) == 1000  # one GPIOR0 1/0 pair per 1 kHz Timer2 tick
    assert 500 < float(s["cyc_mean"]) < 16000
    assert int(s["cyc_min"]) <= float(s["cyc_mean"]) <= int(s["cyc_max"])
    assert int(s["overruns"]) == 0


def test_uart_receive_path(selftest):
    _, port = selftest
    port.reset_input_buffer()
    port.write(b"\x5a")
    lines = read_lines(port, 0.5)
    assert "E 5a" in lines


@pytest.mark.parametrize(
    ("mode", "check"),
    [
        ("error", lambda w: w & 0x4000 and parity_even(w)),
        ("high", lambda w: w == 0xFFFF),
        ("low", lambda w: w == 0x0000),
        ("parity", lambda w: not parity_even(w)),
    ],
)
def test_encoder_fault_injection(selftest, mode, check):
    h, port = selftest
    assert h.command(f"fault 2 {mode}") == f"OK fault 2 {mode}"
    time.sleep(0.1)
    port.reset_input_buffer()
    frames = angle_frames(read_lines(port, 0.3))
    assert h.command("clear 2") == "OK clear 2"
    assert frames
    assert all(check(words[2]) for _, words in frames[1:]), [hex(w[2]) for _, w in frames]
    assert all(parity_even(words[1]) and not words[1] & 0x4000 for _, words in frames)


def test_final_line_on_sigterm():
    with Harness(SELFTEST_ELF, ["--free", "--stats-period", "0.5"]) as h:
        h.latest_stats()
        final = h.stop()
    assert final is not None, h.tail()
    assert float(final["t_s"]) >= 0.5
    assert int(final["steps"]) > 0


def test_runs_fixed_simulated_time():
    with Harness(SELFTEST_ELF, ["--free", "--time", "2"]) as h:
        h.proc.wait(timeout=30)
        h.stop()
    assert h.proc.returncode == 0
    assert float(h.final["t_s"]) == pytest.approx(2.0, abs=0.01)
    # the first ~40 ms go to selftest.c's sine-table set-up before the tick starts
    assert 1900 < int(h.final["steps"]) <= 2000


def test_fault_from_start_and_pty_link(tmp_path):
    link = tmp_path / "wheelboard"
    with Harness(SELFTEST_ELF, ["--rate", "4", "--enc-fault", "0:high", "--pty-link", str(link)]):
        assert link.is_symlink()
        port = serial.Serial(str(link), 500000, timeout=0.2)
        try:
            frames = angle_frames(read_lines(port, 0.5))
        finally:
            port.close()
    assert frames
    assert all(words[0] == 0xFFFF for _, words in frames)
    assert not link.exists(), "the link outlives the harness"
