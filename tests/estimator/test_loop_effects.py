"""The run loop's effects injected one at a time into the in-process SIL (simulated clock,
deterministic): IMU samples stamped on arrival break the filter's consistency, the IMU's
reconstructed grid (what the run loop fuses at) restores most of it. The figures per effect:
``python -m gyrohost.experiments.estimator_effects`` (docs/estimator.md)."""

import numpy as np
import pytest

from gyrohost.config import load_rig_config
from gyrohost.experiments.estimator_effects import CASES, score_with_effects
from gyrohost.resources import shipped

CONFIG = load_rig_config(shipped("config", "sim-rig"))


@pytest.fixture(scope="module")
def nees():
    def mean_nees(case):
        r = score_with_effects(CONFIG, 2, CASES[case], duration_s=1.0, delay_s=2e-3)
        return float(np.mean(r.nees[r.t_s >= 0.2]))

    return {case: mean_nees(case) for case in ("sil", "imu-arrival", "imu-regrid")}


def test_arrival_stamps_break_consistency_and_the_grid_restores_it(nees):
    # over 0.2-1 s string s24 crosses its kink: the SIL itself is above its dof (25) there
    assert nees["imu-arrival"] > 5.0 * nees["sil"], nees
    assert nees["imu-regrid"] < 0.25 * nees["imu-arrival"], nees


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
