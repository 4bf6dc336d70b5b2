"""A short run of the D-bar on the simulated rig, as a lab records one, for the tests that read
its log."""

import subprocess
import sys
from pathlib import Path


def sim_run_log(root: Path, schedule_text: str) -> Path:
    """``gyrotens run --sim`` of the shipped sim-rig playing the schedule ``schedule_text``
    (TOML), run in ``root``; its log folder ``root/log``."""
    (root / "schedule.toml").write_text(schedule_text)
    cmd = [sys.executable, "-m", "gyrohost", "run", "--sim", "--schedule", "schedule.toml",
           "-o", "log"]  # fmt: skip
    proc = subprocess.run(cmd, cwd=root, capture_output=True, text=True, timeout=300)
    # the tests read what the run logged: a loaded machine can make its estimate diverge (exit 1)
    assert proc.returncode == 0 or "gyrotens run: completed" in proc.stderr, proc.stderr
    return root / "log"
