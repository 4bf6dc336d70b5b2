"""Run one study and write its dated report: ``python -m studies NAME [ARGS...]``.

``python -m studies`` alone lists the studies with what each measures and how long its last run
took;
``python -m studies --check`` imports every study and parses its ``--help`` (what ``make test``
runs, so that a study cannot rot unnoticed while the tests never import one).

A study's printed figures go to the terminal and into ``reports/NAME.md`` (``--reports DIR``
elsewhere), headed by the date, the command, the machine (CPU, Python, numpy and its BLAS) and
the wall time: a figure is worth only as much as the machine and the command that made it.
"""

import argparse
import contextlib
import importlib
import io
import platform
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

STUDIES = {
    "estimator_montecarlo": "the EKF's NEES/NIS on synthetic runs over seeds",
    "estimator_sil": "the EKF's NEES/NIS on the simulated rig's truth and emulators over seeds",
    "estimator_effects": "the run loop's timing effects on consistency, one at a time",
    "estimator_benchmark": "the filter's time per IMU sample and per Jacobian",
    "identify_check": "identification accuracy and coverage over seeds (simulated clock)",
    "identify_rig": "identification end to end on the real-time rig, then a run with it",
    "identify_preset": "identification from the preset schedules, per segment",
    "identify_transfer": "the identified scene on another manoeuvre than its recording",
    "control_compare": "open vs closed loop on a truth with heavier wheels (in process)",
    "rig_sil": "open vs closed loop on the real-time simulated rig",
    "mujoco_peer": "the fast path against MuJoCo on the same scene",
}
"""Study -> what it measures."""

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
    blas = ""
    with contextlib.suppress(ImportError):
        from threadpoolctl import threadpool_info

        blas = ", ".join(
            f"{i.get('internal_api')} {i.get('architecture', '')}".strip()
            for i in threadpool_info()
            if i.get("user_api") == "blas"
        )
    return f"{cpu}; Python {platform.python_version()}; numpy {np.__version__}; BLAS {blas or '?'}"


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


def run_study(name: str, argv: list[str], reports: Path) -> int:
    """Run study ``name`` with ``argv``, write ``reports/NAME.md``; the study's exit status."""
    module = importlib.import_module(f"studies.{name}")
    start, when = time.perf_counter(), datetime.now(timezone.utc)
    tee = Tee(sys.stdout)
    with contextlib.redirect_stdout(tee):
        status = module.main(argv)
    wall_s = time.perf_counter() - start
    reports.mkdir(parents=True, exist_ok=True)
    path = reports / f"{name}.md"
    command = " ".join(["python -m studies", name, *argv])
    path.write_text(
        f"# {name}: {STUDIES[name]}\n\n"
        f"- date: {when:%Y-%m-%d %H:%M} UTC\n- command: `{command}`\n"
        f"- machine: {machine()}\n- wall time: {wall_s:.0f} s; exit status {status}\n\n"
        f"{(module.__doc__ or '').strip()}\n\n## Output\n\n```\n{tee.lines.getvalue()}```\n"
    )
    print(f"report: {path} ({wall_s:.0f} s)", file=sys.stderr)
    return status


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
    print(f"studies: {len(STUDIES) - len(broken)} passed, {len(broken)} failed")
    return 1 if broken else 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m studies", description=__doc__.split("\n")[0])
    parser.add_argument("name", nargs="?", choices=sorted(STUDIES), help="the study to run")
    parser.add_argument("args", nargs=argparse.REMAINDER, help="the study's own options")
    parser.add_argument("--check", action="store_true", help="import and --help every study")
    parser.add_argument("--reports", type=Path, default=ROOT / "reports", help="report folder")
    args = parser.parse_args(argv)
    if args.check:
        return check()
    if args.name is None:
        for name, what in STUDIES.items():
            print(f"{name:22s} {what}; {last_run(args.reports / f'{name}.md')}")
        return 0
    return run_study(args.name, args.args, args.reports)


if __name__ == "__main__":
    sys.exit(main())
