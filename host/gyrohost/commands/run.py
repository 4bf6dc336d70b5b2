"""``gyrotens run --config RIG.toml [--schedule FILE|PRESET] [-o LOGDIR] [--sim]``: one run of a
schedule on the rig, from connection to the safe state, logged (docs/run.md)."""

import sys
import time
from pathlib import Path

from gyrohost.config import EMULATED_PORT


def register(sub) -> None:
    p = sub.add_parser("run", help="run a schedule on the rig (hardware, ptys or --sim) and log it")
    p.add_argument("--config", type=Path, required=True, help="rig configuration (TOML)")
    p.add_argument(
        "--schedule",
        default="paper",
        help="schedule file (.toml/.json, docs/schedule.md) or preset name (default: paper)",
    )
    p.add_argument("-o", "--out", type=Path, help="log folder (default: out/runs/<time>-<scene>)")
    p.add_argument("--sim", action="store_true", help="start the simulated rig in this process")
    p.add_argument("--scene", type=Path, help="scene file (default: the configuration's)")
    for dev in ("imu", "wheels", "servos"):
        p.add_argument(f"--{dev}", metavar="PORT", help=f"{dev} port (overrides the configuration)")
    p.set_defaults(func=run)


def load_schedule_arg(text: str, scene_path: Path):
    """A schedule file, or a preset built for the scene at ``scene_path``."""
    from gyrohost.control.presets import PRESETS, preset
    from gyrohost.control.schedule import load_schedule
    from gyrotensegrity import Model, load_scene

    if text in PRESETS:
        return preset(text, Model(load_scene(scene_path)))
    return load_schedule(Path(text))


class Progress:
    """One status line on a terminal: phase, time, schedule played; silent otherwise."""

    def __init__(self, label: str = "", stream=None):
        self.label, self.stream = label, stream or sys.stderr
        self.enabled = self.stream.isatty()
        self._last = 0.0

    def __call__(self, phase: str, t_s: float, fraction: float) -> None:
        now = time.monotonic()
        if self.enabled and now - self._last > 0.1:
            self._last = now
            bar = "#" * int(25 * fraction)
            self.stream.write(f"\r{self.label}[{bar:<25}] {phase:<9} t = {t_s:6.2f} s")
            self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\n")


def _wired(config, args):
    from gyrohost.cli import CliError
    from gyrohost.runloop import with_ports

    config = with_ports(config, {"imu": args.imu, "wheels": args.wheels, "servos": args.servos})
    emulated = [
        name
        for name, port in (
            ("imu", config.imu.port),
            ("wheels", config.wheelboard.port),
            ("servos", config.servos.port),
        )
        if port == EMULATED_PORT
    ]
    if emulated:
        raise CliError(
            f"{args.config}: port(s) of {', '.join(emulated)} are '{EMULATED_PORT}': add --sim, "
            "or give the ptys printed by 'gyrotens rig' with --imu/--wheels/--servos"
        )
    return config


def run(args) -> int:
    from dataclasses import replace

    from gyrohost.cli import CliError
    from gyrohost.config import ConfigError, load_rig_config
    from gyrohost.control.errors import ScheduleError
    from gyrohost.rig.truth import RigSetupError
    from gyrohost.rig_process import RigProcessError
    from gyrohost.runloop import RunLoop, ScheduleRefused, run_simulated
    from gyrotensegrity import SceneError

    try:
        config = load_rig_config(args.config)
        if args.scene is not None:
            config = replace(config, scene=str(args.scene.resolve()))
        schedule = load_schedule_arg(args.schedule, config.scene_path)
    except (ConfigError, ScheduleError, SceneError, OSError) as exc:
        raise CliError(str(exc)) from None
    out = args.out or Path("out/runs") / f"{time.strftime('%Y%m%d-%H%M%S')}-{schedule.name}"
    if (out / "meta.json").exists():
        raise CliError(f"{out}: already holds a log; choose another -o")
    progress = Progress()
    meta = {"command": sys.argv}
    try:
        if args.sim:
            result = run_simulated(config, schedule, out, progress=progress, meta=meta)
        else:
            loop = RunLoop(_wired(config, args), schedule, out, progress=progress, meta=meta)
            result = loop.run()
    except (ScheduleRefused, ScheduleError, RigSetupError, SceneError, RigProcessError) as exc:
        raise CliError(str(exc)) from None
    finally:
        progress.close()
    return report(result)


def report(result) -> int:
    """Print how a run ended and where its log is; returns its exit status."""
    from gyrohost.run_records import jitter_line

    s = result.summary
    print(f"log: {result.log_folder}")
    print(jitter_line(s["loop"]))
    if "tilt_end_estimate_rad" in s:
        line = f"tilt at the end of the schedule: estimate {s['tilt_end_estimate_rad']:+.4f} rad"
        if "tilt_end_truth_rad" in s:
            line += f", truth {s['tilt_end_truth_rad']:+.4f} rad"
        print(line)
    if result.exit_status:
        print(f"gyrotens run: stopped in the safe state: {result.reason}", file=sys.stderr)
    else:
        print("run completed; rig in the safe state (wheels stopped, servos holding)")
    return result.exit_status
