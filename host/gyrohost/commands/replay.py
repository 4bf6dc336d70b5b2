"""``gyrotens replay LOG [-o OUT]``: rerun the estimator over a run log (deterministic)."""

import sys
from pathlib import Path

MAX_WARNINGS = 10
"""Warnings printed as they come; the rest are counted (all are in the output's meta.json)."""

COMPARED = (
    ("nodes_m", "nodes", "m"),
    ("velocities_m_s", "velocities", "m/s"),
    ("wheels_rad_s", "wheels", "rad/s"),
    ("rest_lengths_m", "rest lengths", "m"),
    ("gyro_bias_rad_s", "gyro bias", "rad/s"),
)
"""Groups of ``summary.compare_live`` as printed: key, words, unit."""


def register(sub) -> None:
    p = sub.add_parser("replay", help="rerun the estimator over a run log, write a new log")
    p.add_argument("log", type=Path, help="log folder (meta.json + CSV streams)")
    p.add_argument("-o", "--out", type=Path, help="output log folder (default: LOG-replay)")
    p.add_argument("--scene", type=Path, help="scene file (default: 'scene' in meta.json)")
    p.add_argument(
        "--estimator",
        "--config",
        dest="config",
        type=Path,
        metavar="FILE",
        help="estimator settings: a TOML with an [estimator] table, as 'run --estimator' takes "
        "(--config: the old name)",
    )
    p.set_defaults(func=run)


class Warnings:
    """Prints the first :data:`MAX_WARNINGS` warnings of a command to stderr, counts the rest."""

    def __init__(self, command: str):
        self.command, self.count = command, 0

    def __call__(self, message: str) -> None:
        self.count += 1
        if self.count <= MAX_WARNINGS:
            print(f"gyrotens {self.command}: warning: {message}", file=sys.stderr)

    def close(self, where: str = "") -> None:
        """Say how many were not printed (and ``where`` they all are, if they are kept)."""
        if self.count > MAX_WARNINGS:
            print(
                f"gyrotens {self.command}: warning: {self.count - MAX_WARNINGS} more warnings "
                f"not shown ({self.count} in all{f', in {where}' if where else ''})",
                file=sys.stderr,
            )


def run(args) -> int:
    from gyrohost.commands.errors import CliError
    from gyrohost.estimator import EstimatorConfigError, EstimatorError, load_config
    from gyrohost.estimator.ekf import Status
    from gyrohost.run.errors import LogError
    from gyrohost.run.replay import replay
    from gyrotensegrity import SceneError

    out = args.out or args.log.with_name(args.log.name + "-replay")
    warn = Warnings("replay")
    try:
        config = load_config(args.config) if args.config else None
        summary = replay(args.log, out, scene=args.scene, config=config, warn=warn)
    except (LogError, EstimatorConfigError, EstimatorError, SceneError) as exc:
        raise CliError(str(exc)) from None
    warn.close(f"{out}/meta.json, summary.warnings")
    for line in rows_lines(summary["log_rows"]):
        print(line)
    for source, c in summary["sources"].items():
        print(
            f"{source:10s} accepted {c['accepted']:6d}  rejected {c['rejected']:5d}  "
            f"stale {c['stale']:4d}  time-outs {c['timeouts']:3d}"
        )
    status = Status(summary["final_status"])
    names = "|".join(flag.name for flag in Status if flag in status)
    print(f"final status 0x{int(status):04x}{f' ({names})' if names else ''}; wrote {out}")
    print(compare_line(summary["compare_live"]))
    return 0


def compare_line(compared: dict) -> str:
    """The replay's estimate against the run's, largest difference per state group."""
    if not compared:
        return "no estimate of the run in the log to compare with"
    groups = ", ".join(
        f"{words} {compared[key]:.3g} {unit}" for key, words, unit in COMPARED if key in compared
    )
    return f"against the run's estimate ({compared['rows']} rows), largest difference: {groups}"


def rows_lines(log_rows: dict) -> list[str]:
    """The input rows read per stream; for each stream with rows left out, a line of them by
    kind."""
    from gyrohost.run.log_screen import KINDS

    read = ", ".join(f"{stream} {c['rows']}" for stream, c in log_rows.items())
    lines = [f"log rows read: {read}"]
    for stream, counts in log_rows.items():
        left = {kind: counts[kind] for kind in KINDS if counts[kind]}
        if left:
            what = ", ".join(f"{n} {kind.replace('_', '-')}" for kind, n in left.items())
            lines.append(f"  {stream}: {sum(left.values())} not fused ({what})")
    return lines
