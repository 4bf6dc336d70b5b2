"""Run one study and write its dated report: ``python -m studies NAME [ARGS...]``.

``python -m studies GROUP`` (``estimator``, ``identification``) runs each study of the group at
its defaults into one report, the one the docs quote. ``python -m studies`` alone lists the
studies with what each measures and how long its last run took;
``python -m studies --check`` imports every study and parses its ``--help`` (what ``make test``
runs, so that a study cannot rot unnoticed while the tests never import one).

A study's printed figures go to the terminal and into ``reports/NAME.md`` (``--reports DIR``
elsewhere), headed by the date, the machine (CPU, Python, numpy and its BLAS), the command and
the wall time: a figure is worth only as much as the machine and the command that made it.
"""

import argparse
import contextlib
import importlib
import io
import os
import platform
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

STUDIES = {
    "estimator_montecarlo": "the EKF's NEES/NIS on synthetic runs over seeds",
    "estimator_sil": "the EKF's NEES/NIS on the simulated rig's truth and emulators over seeds",
    "estimator_replay": "the EKF replayed over runs recorded on the real-time simulated rig",
    "estimator_effects": "the run loop's timing effects on consistency, one at a time",
    "estimator_benchmark": "the filter's time per IMU sample and per Jacobian",
    "identify_check": "identification accuracy and coverage over seeds (simulated clock)",
    "identify_rig": "identification end to end on the real-time rig, then a run with it",
    "identify_heldout": "the default identification on truths drawn from a prior, held out",
    "identify_preset": "identification from the preset schedules, per segment",
    "identify_transfer": "the identified scene on another manoeuvre than its recording",
    "control_compare": "open vs closed loop on a truth with heavier wheels (in process)",
    "rig_sil": "open vs closed loop on the real-time simulated rig",
    "attitude_open_loop": "three-axis plans played open loop on the full model (prism, dbar-rig)",
    "attitude_closed_loop": "three-axis maneuvers open vs closed loop, truth 1-sigma off",
    "mujoco_peer": "the fast path against MuJoCo on the same scene",
}
"""Study -> what it measures."""
GROUPS = {
    "estimator": (
        "estimator_sil",
        "estimator_replay",
        "estimator_montecarlo",
        "estimator_effects",
        "estimator_benchmark",
    ),
    "identification": ("identify_check", "identify_rig", "identify_heldout"),
}
"""Reports that gather several studies, each run at its defaults (the docs quote these)."""

ROOT = Path(__file__).resolve().parent.parent


def machine() -> str:
    """CPU, Python, numpy and the BLAS kernel: what a round-off-sensitive figure hangs on."""
    import numpy as np

    cpu = platform.processor() or platform.machine()
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    config = np.show_config(mode="dicts")
    blas = config["Build Dependencies"]["blas"]
    core = os.environ.get("OPENBLAS_CORETYPE", "chosen at load")
    simd = ",".join(config.get("SIMD Extensions", {}).get("found", []))
    return (
        f"{cpu}; Python {platform.python_version()}; numpy {np.__version__} (SIMD {simd}); "
        f"BLAS {blas['name']} {blas.get('version', '')}, OPENBLAS_CORETYPE {core}"
    )


class Tee(io.TextIOBase):
    """The study's prints to the terminal and into the report."""

    def __init__(self, terminal):
        self.terminal, self.lines = terminal, io.StringIO()

    def write(self, text):
        self.terminal.write(text)
        self.lines.write(text)
        return len(text)

    def flush(self):
        self.terminal.flush()


def run_one(name: str, argv: list[str]) -> tuple[str, float, int]:
    """Run study ``name`` with ``argv``: its report section, wall time in s and exit status."""
    module = importlib.import_module(f"studies.{name}")
    start = time.perf_counter()
    tee = Tee(sys.stdout)
    with contextlib.redirect_stdout(tee):
        status = module.main(argv)
    wall_s = time.perf_counter() - start
    command = " ".join(["python -m studies", name, *argv])
    section = (
        f"## {name}: {STUDIES[name]}\n\n- command: `{command}`\n"
        f"- wall time: {wall_s:.0f} s; exit status {status}\n\n"
        f"{(module.__doc__ or '').strip()}\n\n```\n{tee.lines.getvalue()}```\n"
    )
    return section, wall_s, status


def run_report(name: str, argv: list[str], reports: Path) -> int:
    """Run a study, or each study of a group at its defaults, into ``reports/NAME.md``."""
    members = GROUPS.get(name, (name,))
    when, runs = datetime.now(UTC), []
    for member in members:
        runs.append(run_one(member, argv if member == name else []))
    wall_s = sum(r[1] for r in runs)
    reports.mkdir(parents=True, exist_ok=True)
    path = reports / f"{name}.md"
    path.write_text(
        f"# Report: {name}\n\n"
        f"- date: {when:%Y-%m-%d %H:%M} UTC\n- machine: {machine()}\n"
        f"- wall time: {wall_s:.0f} s\n\n" + "\n".join(r[0] for r in runs)
    )
    print(f"report: {path} ({wall_s:.0f} s)", file=sys.stderr)
    return max(r[2] for r in runs)


def last_run(report: Path) -> str:
    """How long the study took when its report was last written, or that it has none."""
    with contextlib.suppress(OSError):
        for line in report.read_text().splitlines():
            if line.startswith("- wall time:"):
                return f"last run {line.removeprefix('- wall time: ').split(';')[0]}"
    return "no report yet"


def check() -> int:
    """Import every study and parse its --help; 0 when all do."""
    broken = []
    for name in STUDIES:
        try:
            module = importlib.import_module(f"studies.{name}")
            with contextlib.redirect_stdout(io.StringIO()):
                module.main(["--help"])
        except SystemExit as exc:
            if exc.code not in (0, None):
                broken.append(f"{name}: --help exited {exc.code}")
        except Exception as exc:  # noqa: BLE001 - each broken study is named, not raised
            broken.append(f"{name}: {type(exc).__name__}: {exc}")
    for line in broken:
        print(f"studies: {line}", file=sys.stderr)
    print(f"studies: {len(STUDIES) - len(broken)} of {len(STUDIES)} import and parse their options")
    return 1 if broken else 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m studies", description=__doc__.split("\n")[0])
    names = sorted(STUDIES) + sorted(GROUPS)
    parser.add_argument("name", nargs="?", choices=names, help="the study or group to run")
    parser.add_argument("args", nargs=argparse.REMAINDER, help="the study's own options")
    parser.add_argument("--check", action="store_true", help="import and --help every study")
    parser.add_argument(
        "--reports", type=Path, default=ROOT / "reports", help="report folder (before NAME)"
    )
    args = parser.parse_args(argv)
    if args.check:
        return check()
    if args.name is None:
        for name, what in STUDIES.items():
            print(f"{name:22s} {what}; {last_run(args.reports / f'{name}.md')}")
        for name, members in GROUPS.items():
            print(f"{name:22s} {', '.join(members)}; {last_run(args.reports / f'{name}.md')}")
        return 0
    return run_report(args.name, args.args, args.reports)


if __name__ == "__main__":
    sys.exit(main())
