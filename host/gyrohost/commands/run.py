"""``gyrotens run --config RIG.toml [--overlay FILE] [--schedule FILE|PRESET | --target-tilt RAD
| --target-attitude R,P,Y [--strings-only|--wheels-only] [--target-shape FILE]] [--duration S]
[--closed-loop]]
[--max-duration S] [--estimator FILE.toml] [-o LOGDIR]
[--sim [--truth-scene FILE] | --rig PORTSFILE] [--live]``: one run of a schedule or a planned
tilt maneuver on the rig, from connection to the safe state, logged (CSV streams and an MCAP
file), optionally served live to Foxglove (docs/run.md, docs/schedule.md)."""

import math
import sys
import time
from pathlib import Path

SILENCE_WARNING = 0.5
"""Share of the wheel board's HEARTBEAT_MS the host may leave it without a frame before
``gyrotens run`` warns."""


def register(sub) -> None:
    p = sub.add_parser("run", help="run a schedule on the rig (hardware, ptys or --sim) and log it")
    p.add_argument(
        "--config",
        default="sim-rig",
        help="rig configuration: a TOML file or a shipped name (default sim-rig, for --sim)",
    )
    p.add_argument(
        "--overlay",
        type=Path,
        action="append",
        default=[],
        metavar="FILE",
        help="TOML keys merged into the configuration (gyrotens identify's: IMU mounting, "
        "servo zeros); repeatable",
    )
    p.add_argument(
        "--schedule",
        help="schedule file (.toml/.json, docs/schedule.md), preset or shipped schedule name "
        "(default: paper)",
    )
    p.add_argument(
        "--target-tilt",
        type=float,
        metavar="RAD",
        help="plan a maneuver landing the D-bar plane at this tilt (instead of --schedule)",
    )
    p.add_argument(
        "--target-attitude",
        metavar="ROLL,PITCH,YAW",
        help="plan a maneuver landing the scene's body frame at this attitude, degrees "
        "(intrinsic Z-Y-X, as gyrotens plan; docs/attitude-plans.md), on strings and wheels",
    )
    only = p.add_mutually_exclusive_group()
    only.add_argument(
        "--strings-only", action="store_true", help="--target-attitude: hold the wheels' spins"
    )
    only.add_argument(
        "--wheels-only", action="store_true", help="--target-attitude: hold the rest lengths"
    )
    p.add_argument(
        "--target-shape",
        type=Path,
        metavar="FILE",
        help="--target-attitude: land at these rest lengths (as gyrotens plan)",
    )
    p.add_argument(
        "--duration", type=float, default=4.0, metavar="S", help="landing time of the target"
    )
    p.add_argument(
        "--closed-loop",
        action="store_true",
        help="re-plan the maneuver from the EKF's estimate every --replan-period",
    )
    p.add_argument("--replan-period", type=float, default=0.25, metavar="S", help="(0.25 s)")
    p.add_argument(
        "--replan-thread", action="store_true", help="re-plan in a worker thread, off the loop"
    )
    p.add_argument(
        "--estimator",
        type=Path,
        metavar="FILE",
        help="TOML with an [estimator] table; its keys override the rig configuration's",
    )
    p.add_argument(
        "--max-duration",
        type=float,
        metavar="S",
        help="refuse a schedule longer than S seconds (default 600)",
    )
    p.add_argument("-o", "--out", type=Path, help="log folder (default: out/runs/<time>-<scene>)")
    p.add_argument("--sim", action="store_true", help="start the simulated rig in this process")
    p.add_argument("--scene", help="scene file or shipped name (default: the configuration's)")
    p.add_argument(
        "--truth-scene",
        metavar="FILE",
        help="with --sim: the scene of the rig's truth, not the host's (default: [sim.truth] "
        "scene)",
    )
    p.add_argument(
        "--rig",
        type=Path,
        metavar="PORTSFILE",
        help="the ports of a running 'gyrotens rig', from the ports file it printed "
        "(instead of the configuration's ports)",
    )
    for dev in ("imu", "wheels", "servos"):
        p.add_argument(
            f"--{dev}", metavar="PORT", help=f"{dev} port (overrides the configuration and --rig)"
        )
    p.add_argument(
        "--live",
        action="store_true",
        help="serve the run's channels live over a Foxglove WebSocket on localhost "
        "(needs the extra 'live')",
    )
    p.add_argument(
        "--live-port", type=int, default=8765, metavar="PORT", help="(8765; 0: a free port)"
    )
    p.set_defaults(func=run)


class Progress:
    """One status line on a terminal: phase, time, schedule played, the estimated tilt, the
    measured wheel speeds, the estimator's status and the estimated body attitude (roll, pitch,
    yaw of the scene's ``[attitude]`` frame); silent otherwise."""

    def __init__(self, label: str = "", stream=None):
        self.label, self.stream = label, stream or sys.stderr
        self.enabled = self.stream.isatty()
        self._last = 0.0

    def __call__(self, phase: str, t_s: float, fraction: float, readout=None) -> None:
        now = time.monotonic()
        if self.enabled and now - self._last > 0.1:
            self._last = now
            self.stream.write(f"\r{self.line(phase, t_s, fraction, readout)}\033[K")
            self.stream.flush()

    def line(self, phase: str, t_s: float, fraction: float, readout=None) -> str:
        """The status line (``readout``: :meth:`gyrohost.run.RunLoop.readout`)."""
        bar = "#" * int(10 * fraction)
        text = f"{self.label}[{bar:<10}] {phase:<8} t {t_s:6.2f} s"
        if readout is None:
            return text
        if readout.tilt_rad == readout.tilt_rad:  # not NaN: a scene with a tilt, estimated
            text += f" | tilt {readout.tilt_rad:+.3f} rad"
        if readout.omega_rad_s is not None:
            text += " | wheels " + " ".join(f"{w:+5.1f}" for w in readout.omega_rad_s) + " rad/s"
        text += f" | EKF {readout.estimator}"
        if readout.rpy_rad is not None:  # a scene with a body frame, estimated
            angles = " ".join(f"{math.degrees(a):+6.1f}" for a in readout.rpy_rad)
            text += f" | roll pitch yaw {angles} deg"
        return text

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\n")


def run(args) -> int:
    from gyrohost.sigint import InterruptsRaised, exit_status, signal_name

    try:
        with InterruptsRaised():  # SIGTERM, SIGHUP before the run loop: as Ctrl-C there
            return _run(args)
    except KeyboardInterrupt as exc:  # before anything moved, or after the log was written
        print(f"gyrotens run: interrupted ({signal_name(exc)})", file=sys.stderr)
        return exit_status(exc)


def _run(args) -> int:
    from gyrohost.commands.errors import CliError
    from gyrohost.errors import GyrohostError
    from gyrohost.run.request import execute
    from gyrotensegrity import SceneError

    progress = Progress()
    try:
        result = execute(
            _request(args),
            progress,
            meta={"command": sys.argv},
            live_port=args.live_port if args.live else None,
            on_live=_announce_live,
            announce=lambda line: print(line, flush=True),
        )
    except (GyrohostError, SceneError, OSError) as exc:
        raise CliError(str(exc)) from None
    finally:
        progress.close()
    return report(result, args.config)


def _request(args):
    """The :class:`RunRequest` of the options; the options only the command line combines
    checked here."""
    from gyrohost.commands.errors import CliError
    from gyrohost.control.maneuver import Target
    from gyrohost.run.request import RunRequest

    target = None
    aimed = args.target_tilt is not None or args.target_attitude is not None
    if not aimed and (args.closed_loop or args.replan_thread):
        raise CliError("--closed-loop and --replan-thread need --target-tilt or --target-attitude")
    if args.target_tilt is not None and args.target_attitude is not None:
        raise CliError("give --target-tilt or --target-attitude, not both")
    if args.target_attitude is None and (
        args.strings_only or args.wheels_only or args.target_shape
    ):
        raise CliError("--strings-only, --wheels-only and --target-shape go with --target-attitude")
    if args.max_duration is not None and not args.max_duration > 0:  # NaN too
        raise CliError(f"--max-duration {args.max_duration}: must be a positive number of s")
    if aimed:
        target = Target(
            args.target_tilt,
            args.duration,
            closed_loop=args.closed_loop,
            period_s=args.replan_period,
            threaded=args.replan_thread,
            **_attitude(args),
        )
    return RunRequest(
        config=args.config,
        overlays=tuple(args.overlay),
        scene=args.scene,
        truth_scene=args.truth_scene,
        estimator=args.estimator,
        schedule=args.schedule,
        target=target,
        out=args.out,
        sim=args.sim,
        ports_file=args.rig,
        ports={"imu": args.imu, "wheels": args.wheels, "servos": args.servos},
        max_schedule_s=args.max_duration,
    )


def _attitude(args) -> dict:
    """The attitude keys of the :class:`Target` (none for a tilt)."""
    from gyrohost.commands.plan import attitude_angles
    from gyrohost.control.target_shape import load_target_shape

    if args.target_attitude is None:
        return {}
    mode = "strings" if args.strings_only else "wheels" if args.wheels_only else "both"
    shape = None if args.target_shape is None else load_target_shape(args.target_shape)
    return {
        "attitude_rpy_rad": tuple(attitude_angles(args.target_attitude)),
        "mode": mode,
        "target_rest": shape,
    }


def _announce_live(url: str) -> None:
    print(f"live: {url} (Foxglove: Open connection, Foxglove WebSocket)", flush=True)


def report(result, config: str = "sim-rig") -> int:
    """Print how a run ended and where its log is (an identification run: the command that
    fits it, with the rig configuration ``config``); returns its exit status."""
    from gyrohost.run import jitter_line
    from gyrohost.run.health import fails_run, health_lines, rejection_warnings
    from gyrohost.run.safe_state import describe, failed_steps
    from gyrohost.run.summary import link_lines, real_time_lost, sources_line

    s = result.summary
    print(f"log: {result.log_folder}")
    mcap = Path(result.log_folder) / "run.mcap"
    if mcap.exists():
        print(f"mcap: {mcap} (opens in Foxglove)")
    if "loop" in s:  # none if the summary could not be made
        print(jitter_line(s["loop"]))
    silence = s.get("wheel_board_silence_s")
    if silence and silence["max"] > SILENCE_WARNING * silence["limit"]:
        print(
            f"gyrotens run: warning: the host sent the wheel board nothing for "
            f"{1e3 * silence['max']:.0f} ms; at {1e3 * silence['limit']:.0f} ms its fail-safe "
            "stops the wheels (a loaded or stalling host: close other programs)",
            file=sys.stderr,
        )
    lost = real_time_lost(s)
    if lost:
        print(f"gyrotens run: warning: {lost}", file=sys.stderr)
    for line in link_lines(s) + rejection_warnings(s.get("estimator", {})):
        print(f"gyrotens run: warning: {line}", file=sys.stderr)
    if "tilt_end_estimate_rad" in s:
        line = f"tilt at the end of the schedule: estimate {s['tilt_end_estimate_rad']:+.4f} rad"
        if "tilt_end_truth_rad" in s:
            line += f", truth {s['tilt_end_truth_rad']:+.4f} rad"
        print(line)
    if "maneuver" in s:
        print(maneuver_line(s))
    for line in health_lines(s.get("estimator", {"nis": {}})):
        print(line)
    if sources_line(s):
        print(sources_line(s))
    safe = s["safe_state"]
    failed = failed_steps(safe)  # one line each, what the step reached included
    for line in failed:
        print(f"gyrotens run: safe state: {line}", file=sys.stderr)
    if result.exit_status == 0:
        print(f"run completed; rig in the safe state: {describe(safe)}")
        if s.get("schedule_purpose") == "identification":
            print(f"next: gyrotens identify {result.log_folder} -o ident.toml --config {config}")
        return 0
    if result.completed:  # the schedule ran to its end, the log or the estimate did not
        what = (
            "the estimate diverged"
            if fails_run(s.get("estimator", {}))
            else "the log is incomplete"
        )
        print(f"gyrotens run: completed, but {what}", file=sys.stderr)
    else:
        print(f"gyrotens run: stopped in the safe state: {result.reason}", file=sys.stderr)
    print(f"gyrotens run: {describe(safe)}", file=sys.stderr)  # whatever else failed
    return result.exit_status


def maneuver_line(summary: dict) -> str:
    """Target, error of the truth (simulated rig) after settling, re-plans and plan times."""
    m = summary["maneuver"]
    t = m["target"]
    loop = "closed loop" if t["closed_loop"] else "open loop"
    if t.get("attitude_rpy_rad") is None:
        line = f"target {t['tilt_rad']:+.4f} rad at {t['duration_s']:g} s, {loop}"
    else:
        rpy = ", ".join(f"{math.degrees(v):+.2f}" for v in t["attitude_rpy_rad"])
        line = f"target roll, pitch, yaw {rpy} deg at {t['duration_s']:g} s ({t['mode']}), {loop}"
    if "tilt_settled_truth_error_rad" in summary:
        line += f": truth error after settling {summary['tilt_settled_truth_error_rad']:+.4f} rad"
    for key, when in (("end", "at the landing"), ("settled", "after settling")):
        if f"attitude_{key}_truth_error_rad" in summary:
            deg = math.degrees(summary[f"attitude_{key}_truth_error_rad"])
            line += f"; truth {deg:.2f} deg off {when}"
    line += f"; first plan {1e3 * m['first_plan']['plan_time_s']:.1f} ms"
    if m["replans"]:
        line += (
            f"; {m['replans']} re-plans ({m['replans_accepted']} accepted), "
            f"{1e3 * m['replan_time_mean_s']:.1f} ms mean, "
            f"{1e3 * m['replan_time_max_s']:.1f} ms max, {m['replans_late']} longer than the "
            f"{1e3 * t['period_s']:.0f} ms period"
        )
    return line
