"""The wheel, installed into a fresh virtual environment, works from any directory.

Builds the wheel from a copy of the sources (so no earlier build output in ``build/`` can slip
in), installs it with pip into a new venv (dependencies from pip's cache or PyPI) and, in a
temporary directory, simulates a shipped scene and runs the estimator on the shipped simulated
rig's configuration, its scene and the paper's schedule (``gyrotens sil`` on its simulated
clock): the shipped files are found as package data, never through the repository. The demo
itself, in real time, is ``tests/run/test_run_cli.py``'s.
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
def test_wheel_in_a_fresh_venv_finds_its_shipped_files_from_a_temporary_directory(tmp_path):
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
    gyrotens = venv / "bin" / "gyrotens"
    run([gyrotens, "simulate", "dbar-gyro", "-o", "run.npz", "--duration", "0.2"], cwd=work)
    assert (work / "run.npz").is_file()
    sil = ["sil", "--runs", "1", "--duration", "0.5", "--out", "sil"]
    printed = run([gyrotens, *sil], cwd=work, timeout=600).stdout
    assert "NEES" in printed and (work / "sil" / "consistency.png").is_file()
