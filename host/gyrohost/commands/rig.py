"""``gyrotens rig``: serve the simulated rig's three devices on pseudo-terminals in real time.

Prints the device paths (one ``name: path`` line each) and writes them to a ports file
(``gyrohost.simrig.control_socket``; ``gyrotens run --rig PORTSFILE`` reads it), serves until
Ctrl-C (or SIGTERM, SIGHUP) or ``--duration``, then prints the measured rates per device and the
truth step timing. Rig commands (``fault imu silence 2``, ``fault wheels reset``, ``fault servos
overload 1 0.5``, ``stats``, ``reset``: the rig back to the scene's initial state, between two runs;
docs/rig.md) arrive on its control socket (``gyrotens rig --send LINE``) and, while the rig is
the foreground job of an interactive terminal, as lines typed on standard input. Standard input
is never read otherwise, so ``gyrotens rig &`` keeps serving in the background.
"""

import os
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
    p.add_argument(
        "--truth-scene",
        metavar="FILE",
        help="scene the truth runs instead (same members, other parameters; default: the "
        "configuration's [sim.truth] scene, else the model's)",
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
    p.add_argument(
        "--ports-file",
        type=Path,
        metavar="FILE",
        help="write the device paths and the control socket here (TOML; default "
        "$XDG_RUNTIME_DIR/gyrotens/rig-ports.toml); the socket is FILE with suffix .sock",
    )
    p.add_argument(
        "--send",
        metavar="LINE",
        help="send one command to the rig of --ports-file and print its answer, then exit",
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from gyrohost.commands.errors import CliError
    from gyrohost.config import ConfigError, load_rig_config
    from gyrohost.resources import ResourceError, resolve
    from gyrohost.sigint import InterruptsRaised, signal_name
    from gyrohost.simrig.config import with_truth_scene
    from gyrohost.simrig.control_socket import control_path, default_ports_file
    from gyrohost.simrig.errors import HarnessError, RigSetupError
    from gyrohost.simrig.sim import SimulatedRig

    ports_file = args.ports_file or default_ports_file()
    if args.send is not None:
        return _send(ports_file, args.send)
    if args.duration is not None and not args.duration > 0:
        raise CliError(f"--duration must be positive, got {args.duration}")
    if _answers(control_path(ports_file)):
        raise CliError(
            f"{ports_file}: a rig is already serving there; stop it or give another --ports-file"
        )
    try:
        config = load_rig_config(resolve("config", args.config))
        if args.firmware_build is not None:
            config = with_firmware_build(config, args.firmware_build)
        scene = resolve("scene", args.scene) if args.scene is not None else None
        if args.truth_scene is not None:
            config = with_truth_scene(config, resolve("scene", args.truth_scene))
    except (ConfigError, ResourceError, HarnessError) as exc:
        raise CliError(str(exc)) from None
    try:
        published = _Published(ports_file)  # before the rig starts: a bad path fails at once
    except OSError as exc:
        raise CliError(
            f"{ports_file}: cannot open the control socket there: {exc.strerror or exc}"
        ) from None
    with InterruptsRaised(), published as control:  # kill (SIGTERM) cleans up as Ctrl-C does
        try:
            rig = SimulatedRig(config, clock="real", scene=scene, wheels=args.wheel_board)
        except (ConfigError, ResourceError, HarnessError, RigSetupError) as exc:
            raise CliError(str(exc)) from None
        with rig:
            try:
                control.publish(rig.paths)
            except OSError as exc:
                raise CliError(f"{ports_file}: cannot write: {exc.strerror or exc}") from None
            _print_header(rig, ports_file, control.path)
            try:
                _serve(rig, args.duration, control)
            except KeyboardInterrupt as exc:
                print(f"stopped by {signal_name(exc)}", flush=True)
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
    from gyrohost.simrig.config import with_sim_keys
    from gyrohost.simrig.simavr import build_binaries

    elf, harness = build_binaries(build_dir)
    return with_sim_keys(
        config, "wheels", simavr_elf=str(elf.resolve()), simavr_harness=str(harness.resolve())
    )


class _Published:
    """The control socket and the ports file, for the life of the rig: removed at the end (the
    ports file only if it is still this rig's)."""

    def __init__(self, ports_file: Path):
        from gyrohost.simrig.control_socket import ControlServer, control_path

        self.ports_file = ports_file
        self.server = ControlServer(control_path(ports_file))
        self.path = self.server.path
        self._text = None

    def publish(self, paths: dict) -> None:
        """Write the ports file: the rig's device ``paths`` and the control socket."""
        from gyrohost.simrig.control_socket import write_ports_file

        write_ports_file(self.ports_file, paths, self.path)
        self._text = self.ports_file.read_text()

    def __enter__(self) -> "_Published":
        return self

    def __exit__(self, *exc) -> None:
        self.server.close()
        try:
            if self._text is not None and self.ports_file.read_text() == self._text:
                self.ports_file.unlink()
        except OSError:
            pass  # removed or replaced already: not ours to remove


def _answers(path: Path) -> bool:
    """A rig listens on the control socket ``path``."""
    import socket

    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        try:
            sock.connect(str(path))
        except OSError:
            return False
    return True


def _send(ports_file: Path, line: str) -> int:
    from gyrohost.commands.errors import CliError
    from gyrohost.simrig.control_socket import read_ports_file, send_command
    from gyrohost.simrig.errors import ControlError, PortsFileError

    try:
        answer = send_command(read_ports_file(ports_file).control, line)
    except (PortsFileError, ControlError) as exc:
        raise CliError(str(exc)) from None
    print(answer)
    return 1 if answer.startswith("error:") else 0


def _print_header(rig, ports_file: Path, control: Path) -> None:
    model = rig.truth.model
    print(
        f"rig: scene {model.scene.name} ({model.describe()}), truth step "
        f"{1e3 * rig.truth.dt_s:g} ms, real time, wheel board: {rig.wheels_kind}",
    )
    for name, path in rig.paths.items():
        print(f"{name}: {path}")
    print(f"ports file: {ports_file}  (gyrotens run --rig {ports_file})")
    print(f"control: {control}  (gyrotens rig --ports-file {ports_file} --send LINE)")
    print(
        "commands: 'fault DEVICE FAULT [ARGS]', 'stats', 'reset' (back to the scene's initial "
        "state, between runs) or 'release' (a held truth's structure let go), typed here while "
        "in the foreground or sent with --send; Ctrl-C stops",
        flush=True,
    )


def _serve(rig, duration_s: float | None, control) -> None:
    end = None if duration_s is None else time.monotonic() + duration_s
    stdin = sys.stdin if _interactive(sys.stdin) else None
    while end is None or time.monotonic() < end:
        if rig.loop_error is not None:
            return
        wait = STDIN_POLL_S if end is None else max(min(STDIN_POLL_S, end - time.monotonic()), 0)
        # a background job reading its terminal is stopped (SIGTTIN): read only in the foreground
        typed = [stdin] if stdin is not None and _foreground(stdin) else []
        ready, _, _ = select.select([*typed, *control.server.sockets()], [], [], wait)
        for sock in ready:
            if sock is stdin:
                line = stdin.readline()
                if not line:  # end of input: keep serving
                    stdin = None
                elif line.strip():
                    print(_answer(rig, line), flush=True)
                continue
            control.server.handle(sock, lambda text: _logged_answer(rig, text))


def _logged_answer(rig, line: str) -> str:
    """The answer to a control ``line``, printed before the client gets it: a client that stops
    the rig (SIGINT) as soon as it has the answer still finds the line in the rig's output."""
    answer = _answer(rig, line)
    print(f"control: {line}: {answer}", flush=True)
    return answer


def _answer(rig, line: str) -> str:
    from gyrohost.simrig.errors import FaultCommandError

    try:
        return rig.command(line)
    except FaultCommandError as exc:
        return f"error: {exc}"


def _interactive(stream) -> bool:
    """``stream`` is an open interactive terminal."""
    try:
        return not stream.closed and os.isatty(stream.fileno())
    except (AttributeError, OSError, ValueError):
        return False


def _foreground(stream) -> bool:
    """This process is the foreground job of the terminal ``stream``."""
    try:
        return os.tcgetpgrp(stream.fileno()) == os.getpgrp()
    except OSError:
        return False
