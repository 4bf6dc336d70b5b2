"""The run loop's effects injected one at a time into the in-process SIL (simulated clock,
deterministic): IMU samples stamped on arrival break the filter's consistency, the IMU's
reconstructed grid (what the run loop fuses at) restores most of it; servo goals held back to
the servo worker's next read break it, sent at once they do not, and late servo reads stamped
when sampled are as good as reads on time. The figures per effect:
``python -m gyrohost.sil.effects`` (docs/estimator.md)."""

from pathlib import Path

import numpy as np
import pytest

from gyrohost.config import load_rig_config
from gyrohost.resources import shipped
from gyrohost.sil.effects import CASES, score_with_effects
from gyrohost.simrig.config import truth_scene_path

CONFIG = load_rig_config(shipped("config", "sim-rig"))


@pytest.fixture(scope="module")
def runs():
    cases = ("sil", "imu-arrival", "imu-regrid", "loop-fixed", "servo-cycle", "servo-read-arrival")
    return {
        case: score_with_effects(CONFIG, 2, CASES[case], duration_s=1.0, delay_s=2e-3)
        for case in cases
    }


@pytest.fixture(scope="module")
def nees(runs):
    return {case: float(np.mean(r.nees[r.t_s >= 0.2])) for case, r in runs.items()}


@pytest.fixture(scope="module")
def servo_nis(runs):
    return {case: float(np.mean(r.nis["servos"][1])) for case, r in runs.items()}


def test_arrival_stamps_break_consistency_and_the_grid_restores_it(nees):
    # over 0.2-1 s string s24 crosses its kink: the SIL itself is above its dof (25) there
    assert nees["imu-arrival"] > 5.0 * nees["sil"], nees
    assert nees["imu-regrid"] < 0.25 * nees["imu-arrival"], nees


def test_servo_goals_must_go_out_at_the_tick_the_filter_is_told(nees):
    assert nees["servo-cycle"] > 5.0 * nees["loop-fixed"], nees


def test_late_servo_reads_are_stamped_when_sampled(nees, servo_nis):
    # loop-fixed reads the servos 8 ms late, stamps them when sampled and takes the filter's
    # rest lengths back to then; stamped on arrival, they disagree with the rest lengths
    assert servo_nis["servo-read-arrival"] > 5.0 * servo_nis["loop-fixed"], servo_nis
    assert servo_nis["loop-fixed"] < 2.0 * 2, servo_nis  # dof 2
    assert nees["loop-fixed"] < 1.5 * nees["sil"], nees


def test_gyrotens_sil_prints_the_consistency_table(capsys, tmp_path):
    from gyrohost.cli import main

    figure = tmp_path / "sil.png"
    assert main(["sil", "--runs", "1", "--duration", "0.3", "--plot", str(figure)]) == 0
    out = capsys.readouterr().out
    assert f"[sil] step-by-step NEES and NIS with their bounds: {figure}" in out
    assert figure.read_bytes()[:4] == b"\x89PNG"
    # without --plot the figure goes into the output folder (--out), for either clock
    assert main(["sil", "--runs", "1", "--duration", "0.3", "--out", str(tmp_path / "o")]) == 0
    assert (tmp_path / "o" / "consistency.png").read_bytes()[:4] == b"\x89PNG"
    assert str(tmp_path / "o" / "consistency.png") in capsys.readouterr().out
    assert "SIL (simulated clock): 1 runs" in out
    for name in ("NEES", "NIS imu_rate", "NIS imu_accel", "NIS imu_angle", "NIS wheels"):
        assert f"[sil] {name}: mean " in out and "95 % bounds of a 1-run average" in out, name
    assert "time steps inside" in out and "tilt error RMS" in out and "filter CPU" in out
    assert main(["sil", "--runs", "0"]) == 2
    assert main(["sil", "--realtime", "--workers", "2"]) == 2  # real time runs one at a time


def test_gyrotens_sil_takes_the_run_commands_overlay_and_scenes(tmp_path, monkeypatch, capsys):
    """``--overlay``, ``--scene`` and ``--truth-scene`` build the configuration the SIL runs,
    as ``gyrotens run`` builds it: an identified scene and overlay checked against a truth;
    a missing or broken file is an error line naming it, not a traceback."""
    import gyrohost.sil.scoring as sil
    from gyrohost.cli import main

    seen = {}

    def capture(config, *args):
        seen["config"] = config
        raise sil.SilError("captured")

    monkeypatch.setattr(sil, "sil_results", capture)
    scene = Path(shipped("scene", "dbar-gyro")).read_text()
    (tmp_path / "host.toml").write_text(scene.replace('name = "dbar-gyro"', 'name = "host"'))
    (tmp_path / "overlay.toml").write_text("[imu]\nmounting_rpy_rad = [0.01, -0.02, 0.03]\n")
    argv = ["sil", "--runs", "1", "--overlay", str(tmp_path / "overlay.toml"),
            "--scene", str(tmp_path / "host.toml"), "--truth-scene", "dbar-rig"]  # fmt: skip
    assert main(argv) == 2
    config = seen["config"]
    assert config.imu.mounting_rpy_rad == (0.01, -0.02, 0.03)
    assert Path(config.scene_path) == tmp_path / "host.toml"
    assert Path(truth_scene_path(config)) == Path(shipped("scene", "dbar-rig"))
    assert "captured" in capsys.readouterr().err
    monkeypatch.undo()
    (tmp_path / "broken.toml").write_text("x = [")
    for option, value in (("--truth-scene", "nope"), ("--scene", "broken.toml"),
                          ("--overlay", "missing.toml")):  # fmt: skip
        assert main(["sil", "--runs", "1", "--duration", "0.3", option, str(tmp_path / value)]) == 2
        assert f"gyrotens sil: error: {tmp_path / value}" in capsys.readouterr().err, option
