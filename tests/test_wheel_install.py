"""The wheel, installed into a fresh virtual environment, runs the demo from any directory.

Builds the wheel from a copy of the sources (so no earlier build output in ``build/`` can slip
in), installs it with pip into a new venv (dependencies from pip's cache or PyPI) and runs
``gyrotens demo`` in a temporary directory: the shipped configuration and scenes are found as
package data, never through the repository.
"""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ("pyproject.toml", "setup.py", "README.md", "model", "host")
IGNORE = shutil.ignore_patterns("__pycache__", "*.so", "*.egg-info")


def run(cmd, **kwargs) -> subprocess.CompletedProcess:
    done = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, **kwargs)
    assert done.returncode == 0, f"{' '.join(map(str, cmd))}:\n{done.stdout}\n{done.stderr}"
    return done


@pytest.mark.slow
def test_wheel_in_a_fresh_venv_runs_the_demo_from_a_temporary_directory(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    for name in SOURCES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, src / name, ignore=IGNORE)
        else:
            shutil.copy2(ROOT / name, src / name)
    built = run([sys.executable, "-m", "pip", "wheel", src, "--no-deps", "-w", tmp_path / "dist"])
    assert "deprecat" not in (built.stdout + built.stderr).lower()
    (wheel,) = (tmp_path / "dist").glob("gyrotensegrity-*.whl")
    venv = tmp_path / "venv"
    run([sys.executable, "-m", "venv", venv])
    run([venv / "bin" / "python", "-m", "pip", "install", "-q", wheel])
    work = tmp_path / "elsewhere"
    work.mkdir()
    out = work / "demo"
    run([venv / "bin" / "gyrotens", "demo", "-o", out, "--duration", "2"], cwd=work, timeout=600)
    for name in ("gyro/meta.json", "nospin/meta.json", "fig7-spin-vs-nospin.png", "summary.md"):
        assert (out / name).is_file(), name
    assert "| wheels at 715 rpm |" in (out / "summary.md").read_text()
