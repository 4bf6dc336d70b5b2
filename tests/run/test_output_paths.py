"""Where commands write: names read from files stay one path component, and ``-o`` folders that
cannot take the output are refused in one line (exit 2) before anything is created."""

import os
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from gyrohost.cli import main
from gyrohost.resources import safe_name, shipped
from gyrotensegrity import Model, load_scene, simulate

CONFIG = shipped("config", "sim-rig")


def listing(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.mark.parametrize(
    ("text", "name"),
    [("../../x", "_.._x"), ("/etc/passwd", "_etc_passwd"), ("..", "run"), ("", "run"),
     ("tilt+0.3 rad", "tilt+0.3_rad"), ("a\\b:c\n", "a_b_c_"), ("x" * 100, "x" * 64)],
)  # fmt: skip
def test_a_name_from_a_file_becomes_one_safe_component(text, name):
    assert safe_name(text) == name
    assert Path(safe_name(text)).name == safe_name(text) not in ("", ".", "..")


def test_run_o_that_is_a_file_is_refused(tmp_path, capsys):
    target = tmp_path / "a-file"
    target.write_text("mine\n")
    assert main(["run", "--sim", "--config", str(CONFIG), "-o", str(target)]) == 2
    assert capsys.readouterr().err == f"gyrotens run: error: {target} is a file, not a folder\n"
    assert target.read_text() == "mine\n" and listing(tmp_path) == ["a-file"]


def test_run_o_under_a_file_is_refused(tmp_path, capsys):
    (tmp_path / "a-file").write_text("mine\n")
    target = tmp_path / "a-file" / "log"
    assert main(["run", "--sim", "-o", str(target)]) == 2
    err = capsys.readouterr().err
    assert err == f"gyrotens run: error: {target}: its parent {tmp_path / 'a-file'} is a file, " \
        "not a folder\n"  # fmt: skip
    assert listing(tmp_path) == ["a-file"]


@pytest.mark.parametrize(
    "files", [["imu.csv"], ["meta.json"], ["a.csv", "b.csv", "c.csv", "d.csv"]]
)
def test_run_o_holding_log_files_is_refused(files, tmp_path, capsys):
    target = tmp_path / "log"
    target.mkdir()
    for name in files:
        (target / name).write_text("t_s\n")
    assert main(["run", "--sim", "-o", str(target)]) == 2
    listed = ", ".join(files[:3]) + (", ..." if len(files) > 3 else "")
    assert capsys.readouterr().err == (
        f"gyrotens run: error: {target}: already holds a log ({listed}); choose another folder\n"
    )
    assert listing(tmp_path) == ["log"] + [f"log/{n}" for n in files]


def _as_unprivileged(cmd):
    """``cmd`` as a user that file permissions apply to (root ignores them: a user namespace
    without a mapping drops that)."""
    if os.geteuid() != 0:
        return cmd
    assert shutil.which("unshare"), "root without unshare cannot test permissions"
    return ["unshare", "--user", *cmd]


@pytest.mark.parametrize("command", ["run", "demo", "replay", "plot"])
def test_a_read_only_o_is_one_line_and_nothing_is_written(command, tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    out = locked / "out"
    args = {
        "run": ["run", "--sim", "--config", str(CONFIG)],
        "demo": ["demo"],
        "replay": ["replay", str(_tiny_log(tmp_path / "log"))],
        "plot": ["plot", str(_tiny_log(tmp_path / "log"))],
    }[command]
    locked.chmod(0o555)
    try:
        proc = subprocess.run(
            _as_unprivileged([sys.executable, "-m", "gyrohost", *args, "-o", str(out)]),
            capture_output=True, text=True, timeout=120, cwd=tmp_path,
        )  # fmt: skip
    finally:
        locked.chmod(0o755)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == (
        f"gyrotens {command}: error: {locked}: cannot write there: Permission denied\n"
    )
    assert listing(locked) == []


def _tiny_log(folder: Path) -> Path:
    """A log folder with one IMU row, enough for replay and plot to reach their output."""
    from gyrohost.sil.synthetic import write_log

    if not folder.exists():
        import numpy as np

        imu = np.zeros(1, dtype=[("t_s", "f8"), ("omega_x_rad_s", "f8")])
        write_log(folder, {"imu": imu}, shipped("scene", "dbar-gyro"))
    return folder


def test_demo_and_plot_o_that_is_a_file_are_refused(tmp_path, capsys):
    target = tmp_path / "a-file"
    target.write_text("mine\n")
    assert main(["demo", "-o", str(target)]) == 2
    assert capsys.readouterr().err == f"gyrotens demo: error: {target} is a file, not a folder\n"
    assert main(["plot", str(_tiny_log(tmp_path / "log")), "-o", str(target)]) == 2
    assert capsys.readouterr().err == f"gyrotens plot: error: {target} is a file, not a folder\n"
    assert target.read_text() == "mine\n"


def test_plot_of_a_run_file_writes_inside_o_whatever_the_scene_is_called(tmp_path):
    scene = load_scene(shipped("scene", "double-pendulum"))
    model = Model(replace(scene, name="../../escaped"))
    run = simulate(model, duration=0.02)
    run.save(tmp_path / "run.npz")
    (tmp_path / "work").mkdir()
    assert main(["plot", str(tmp_path / "run.npz"), "-o", str(tmp_path / "work" / "figs"),
                 "--no-animation"]) == 0  # fmt: skip
    assert listing(tmp_path) == [
        "run.npz", "work", "work/figs", "work/figs/_.._escaped-constraints.png",
        "work/figs/_.._escaped-invariants.png", "work/figs/_.._escaped-nodes.png",
    ]  # fmt: skip


def test_replay_o_holding_a_stream_file_is_refused(tmp_path, capsys):
    target = tmp_path / "out"
    target.mkdir()
    (target / "estimate.csv").write_text("t_s\n")
    assert main(["replay", str(_tiny_log(tmp_path / "log")), "-o", str(target)]) == 2
    assert capsys.readouterr().err == (
        f"gyrotens replay: error: {target}: already holds a log (estimate.csv); "
        "choose another folder\n"
    )
    assert listing(target) == ["estimate.csv"]
