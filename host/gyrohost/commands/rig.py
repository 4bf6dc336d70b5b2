"""``gyrotens rig``: serve the simulated rig's three devices on pseudo-terminals in real time.

Prints the device paths (one ``name: path`` line each), serves until Ctrl-C or ``--duration``,
then prints the measured rates per device and the truth step timing. While it runs, lines typed
on standard input are rig commands: ``fault imu silence 2``, ``fault wheels reset``,
``fault servos overload 1 0.5``, ``stats``, ``reset`` (the rig back to the scene's initial state,
between two runs; docs/rig.md).
"""

import select
import sys
import time
from pathlib import Path

DEFAULT_CONFIG = "sim-rig"
STDIN_POLL_S = 0.2


def register(sub) -> None:
    p = sub.add_parser("rig", help="serve the simulated rig (IMU, wheel board, servos) on ptys")
    p.add_argument(
        "--config",
        default=DEFAULT_CONFIG,
        help="rig configuration: a TOML file (docs/rig-config.md) or a shipped name "
        f"(default {DEFAULT_CONFIG})",
    )
    p.add_argument(
        "--scene", help="scene file or shipped scene name (default: the configuration's)"
    )
    p.add_argument("--duration", type=float, help="serve this long, s (default: until Ctrl-C)")
    p.add_argument(
        "--wheel-board",
        choices=("emulator", "simavr"),
        help="wheel board: the Python emulator or the real firmware in the simavr harness "
        "(default: the configuration's [sim.wheels] kind)",
    )
    p.add_argument(
        "--firmware-build",
        type=Path,
        metavar="DIR",
        help="firmware build directory for simavr (avr/*.elf, sim/fil_harness; default "
        "$GYROTENS_FIRMWARE_BUILD or the configuration's simavr_elf/simavr_harness)",
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from gyrohost.cli import CliError
    from gyrohost.config import ConfigError, load_rig_config
    from gyrohost.resources import ResourceError, resolve
    from gyrohost.rig.sim import SimulatedRig
    from gyrohost.rig.simavr import HarnessError
    from gyrohost.rig.truth import RigSetupError

    if args.duration is not None and not args.duration > 0:
        raise CliError(f"--duration must be positive, got {args.duration}")
    try:
        config = load_rig_config(resolve("config", args.config))
        if args.firmware_build is not None:
            config = with_firmware_build(config, args.firmware_build)
        scene = resolve("scene", args.scene) if args.scene is not None else None
        rig = SimulatedRig(config, clock="real", scene=scene, wheels=args.wheel_board)
    except (ConfigError, ResourceError, HarnessError, RigSetupError) as exc:
        raise CliError(str(exc)) from None
    with rig:
        _print_header(rig)
        try:
            _serve(rig, args.duration)
        except KeyboardInterrupt:
            print("stopped by Ctrl-C", flush=True)
        stats = rig.stats()
    print(stats.rates_line())
    print(stats.truth_line(), flush=True)
    if rig.wheels_kind == "simavr":  # after close: the harness's FINAL line
        print(rig.wheels.summary_line(), flush=True)
    if rig.loop_error is not None:
        raise CliError(f"the rig loop failed: {rig.loop_error!r}")
    return 0


def with_firmware_build(config, build_dir: Path):
    """``config`` with ``[sim.wheels] simavr_elf``/``simavr_harness`` of ``build_dir``."""
    from dataclasses import replace

    from gyrohost.rig.simavr import build_binaries

    elf, harness = build_binaries(build_dir)
    wheels = replace(
        config.sim.wheels, simavr_elf=str(elf.resolve()), simavr_harness=str(harness.resolve())
    )
    return replace(config, sim=replace(config.sim, wheels=wheels))


def _print_header(rig) -> None:
    model = rig.truth.model
    print(
        f"rig: scene {model.scene.name} ({model.describe()}), truth step "
        f"{1e3 * rig.truth.dt_s:g} ms, real time, wheel board: {rig.wheels_kind}",
    )
    for name, path in rig.paths.items():
        print(f"{name}: {path}")
    print(
        "type 'fault DEVICE FAULT [ARGS]', 'stats' or 'reset' (back to the scene's initial "
        "state, between runs); Ctrl-C stops",
        flush=True,
    )


def _serve(rig, duration_s: float | None) -> None:
    end = None if duration_s is None else time.monotonic() + duration_s
    stdin = sys.stdin if _readable(sys.stdin) else None
    while end is None or time.monotonic() < end:
        if rig.loop_error is not None:
            return
        wait = STDIN_POLL_S if end is None else max(min(STDIN_POLL_S, end - time.monotonic()), 0)
        if stdin is None:
            time.sleep(wait)
            continue
        ready, _, _ = select.select([stdin], [], [], wait)
        if not ready:
            continue
        line = stdin.readline()
        if not line:  # end of input: keep serving
            stdin = None
        elif line.strip():
            print(_answer(rig, line), flush=True)


def _answer(rig, line: str) -> str:
    from gyrohost.rig.sim import FaultCommandError

    try:
        return rig.command(line)
    except FaultCommandError as exc:
        return f"error: {exc}"


def _readable(stream) -> bool:
    try:
        stream.fileno()
    except (AttributeError, OSError, ValueError):
        return False
    return not stream.closed
