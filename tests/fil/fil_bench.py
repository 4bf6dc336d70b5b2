"""Firmware-in-the-loop figures: control-step cycles and the speed-loop step response.

    python tests/fil/fil_bench.py cycles [--seconds 5]
    python tests/fil/fil_bench.py step [--accel 10000]

``cycles`` runs the wheel-board ELF in the simavr harness with all four wheels at 715 rpm and
prints the control-step cycle figures (GPIOR0 bracket) next to the firmware's own counters.
``step`` commands 0 -> 715 rpm on all wheels and prints rise time, settling time to +-1 % and
overshoot, from the firmware's telemetry and from the harness's rotor model (the true speed).
Both need ``make -C firmware check`` (ELF and harness) and take some 10 s of wall time.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

from control_beat import start_control_thread
from filharness import Harness, firmware_elf, parse_kv, set_offsets, stats_rpm

from gyrohost.drivers.wheelboard import WheelBoard

TARGET_RPM = 715.0
TARGET_RAD_S = TARGET_RPM * 2 * math.pi / 60
TICK_CYCLES = 16000
VECTOR_NAMES = {12: "WDT", 13: "TIMER2_COMPA", 24: "SPI_STC", 25: "USART0_RX", 26: "USART0_UDRE"}
VECTOR_NAMES[27] = "USART0_TX"


def bench_cycles(seconds: float) -> None:
    elf = firmware_elf()
    with Harness(elf, ["--isr-stats"]) as h:
        board = WheelBoard(h.pty)
        try:
            board.connect()
            start_control_thread(board)
            set_offsets(board)
            board.set_speeds([TARGET_RAD_S] * 4)
            while float(h.latest_stats()["t_s"]) < 3.0:  # ramp and settle first
                pass
            window = [h.latest_stats() for _ in range(max(1, round(seconds)))]
            fw = board.stats()
        finally:
            board.close()
    n = sum(int(s["steps"]) for s in window)
    mean = sum(float(s["cyc_mean"]) * int(s["steps"]) for s in window) / n
    lo = min(int(s["cyc_min"]) for s in window)
    hi = max(int(s["cyc_max"]) for s in window)
    rpm = [sum(stats_rpm(s)[i] for s in window) / len(window) for i in range(4)]
    print(f"firmware   {elf}")
    print(f"window     {len(window)} simulated s, {n} control steps, 4 wheels at {TARGET_RPM} rpm")
    print(
        f"cycles     min {lo}  mean {mean:.0f}  max {hi}  "
        f"({100 * lo / TICK_CYCLES:.1f} / {100 * mean / TICK_CYCLES:.1f} / "
        f"{100 * hi / TICK_CYCLES:.1f} % of the {TICK_CYCLES}-cycle tick)"
    )
    print(f"steps/s    {n / len(window):.1f} (1000 expected)")
    print(f"true rpm   {', '.join(f'{r:.1f}' for r in rpm)}")
    print(
        f"firmware   tick_overruns {fw['tick_overruns']}  step_max_us {fw['step_max_us']}  "
        f"tx_dropped {fw['tx_dropped']}"
    )
    for line in h.log:  # whole run: start, ramp, 715 rpm, stop
        if line.startswith("ISR "):
            isr = parse_kv(line)
            name = VECTOR_NAMES.get(int(isr["vector"]), "")
            print(
                f"ISR {isr['vector']:>2} {name:13s} n {isr['n']:>7}  cycles min {isr['cyc_min']}"
                f"  mean {isr['cyc_mean']}  max {isr['cyc_max']}"
            )


def step_figures(t_s: list[float], w: list[float], target: float) -> dict[str, float]:
    """Rise 10-90 %, settling time to +-1 % (last exit from the band) and overshoot, % of target."""
    band = 0.01 * abs(target)
    rise10 = next((t for t, v in zip(t_s, w, strict=True) if v >= 0.1 * target), math.nan)
    rise90 = next((t for t, v in zip(t_s, w, strict=True) if v >= 0.9 * target), math.nan)
    outside = [t for t, v in zip(t_s, w, strict=True) if abs(v - target) > band]
    settled = outside[-1] if outside and outside[-1] < t_s[-1] else math.nan
    return {
        "rise_s": rise90 - rise10,
        "settle_s": settled,
        "overshoot_pct": 100 * (max(w) - target) / target,
        "final": sum(w[-50:]) / len(w[-50:]),
    }


def bench_step(accel: int | None, duration_s: float) -> None:
    elf = firmware_elf()
    tel = []
    with Harness(elf, ["--stats-period", "0.005"]) as h:
        board = WheelBoard(h.pty, on_telemetry=tel.append)
        try:
            board.connect()
            start_control_thread(board)
            set_offsets(board)
            if accel is not None:
                board.set_param("ACCEL_RAD_S2", accel)
            used_accel = board.get_param("ACCEL_RAD_S2")
            time.sleep(0.2)
            first_stats = len(h.stats)
            board.set_speeds([TARGET_RAD_S] * 4)
            time.sleep(duration_s)
        finally:
            board.close()
    # t0: the first control step that drove the wheels (drive != 0), to the tick
    start = next(i for i, s in enumerate(tel) if s.drive[0] != 0.0)
    t0_s = tel[start].t_us * 1e-6 - 0.002  # telemetry every 2 ticks: t0 is within 2 ms
    rep_t = [s.t_us * 1e-6 - t0_s for s in tel[start:]]
    rep_w = [s.omega_rad_s[0] for s in tel[start:]]
    true = [s for s in h.stats[first_stats:] if float(s["t_s"]) >= t0_s]
    true_t = [float(s["t_s"]) - t0_s for s in true]
    true_w = [stats_rpm(s)[0] * 2 * math.pi / 60 for s in true]
    print(f"firmware   {elf}")
    print(f"step       0 -> {TARGET_RPM} rpm, wheel 0, ACCEL_RAD_S2 = {used_accel}")
    for name, t, w in (("telemetry", rep_t, rep_w), ("true (model)", true_t, true_w)):
        f = step_figures(t, w, TARGET_RAD_S)
        print(
            f"{name:13s} rise 10-90 % {f['rise_s'] * 1000:.0f} ms  "
            f"settling +-1 % {f['settle_s'] * 1000:.0f} ms  "
            f"overshoot {f['overshoot_pct']:.2f} %  final {f['final'] * 60 / (2 * math.pi):.1f} rpm"
        )


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("cycles", help="control-step cycles at 715 rpm")
    c.add_argument("--seconds", type=float, default=5.0, help="simulated seconds to average")
    s = sub.add_parser("step", help="speed step response 0 -> 715 rpm")
    s.add_argument("--accel", type=int, default=None, help="ACCEL_RAD_S2 to set (default: keep)")
    s.add_argument("--duration", type=float, default=4.0, help="seconds to record")
    args = ap.parse_args(argv)
    if args.cmd == "cycles":
        bench_cycles(args.seconds)
    else:
        bench_step(args.accel, args.duration)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
