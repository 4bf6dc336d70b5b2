"""``gyrotens replay``: a synthetic run log replayed twice gives identical bytes."""

import filecmp
import json

import numpy as np
import pytest

from gyrohost.cli import main
from gyrohost.run.log import read_meta, read_stream
from gyrohost.sil.synthetic import write_log


@pytest.fixture(scope="module")
def log(tmp_path_factory, synthetic, scene_path):
    _, data = synthetic
    folder = tmp_path_factory.mktemp("logs") / "run"
    write_log(folder, {k: v[v["t_s"] < 0.6] for k, v in data.items()}, scene_path)
    return folder


def test_replay_is_deterministic_bit_for_bit(log, tmp_path, capsys):
    assert main(["replay", str(log), "-o", str(tmp_path / "a")]) == 0
    assert main(["replay", str(log), "-o", str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out
    assert "imu_rate" in out and "final status" in out
    names = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert "estimate.csv" in names and "innov_imu_angle.csv" in names and "meta.json" in names
    match, mismatch, errors = filecmp.cmpfiles(tmp_path / "a", tmp_path / "b", names, shallow=False)
    assert mismatch == [] and errors == [] and sorted(match) == names


def test_replay_output_streams(log, tmp_path):
    out = tmp_path / "r"
    assert main(["replay", str(log), "-o", str(out)]) == 0
    est = read_stream(out, "estimate")
    imu = read_stream(log, "imu")
    assert est["t_s"][-1] == pytest.approx(imu["t_s"][-1])
    assert np.all(np.isfinite(est["tilt_rad"])) and np.all(est["status"] == 0)
    innov = read_stream(out, "innov_imu_rate")
    assert len(innov) == len(imu)
    assert np.all(innov["var_x"] > 0) and np.all(innov["accepted"] == 1)
    meta = read_meta(out)
    assert meta["summary"]["sources"]["imu_angle"]["accepted"] == len(imu)
    assert json.loads((out / "meta.json").read_text())["replay_of"] == str(log)


def test_replay_errors_are_clear(log, tmp_path, capsys):
    assert main(["replay", str(tmp_path / "missing"), "-o", str(tmp_path / "x")]) == 2
    assert "not a log folder" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text("[estimator]\nimu_rate_std_rad_s = -1\n")
    assert main(["replay", str(log), "-o", str(tmp_path / "y"), "--config", str(bad)]) == 2
    assert "imu_rate_std_rad_s" in capsys.readouterr().err


def test_regular_times_spread_bursts_and_cap_the_delay():
    from gyrohost.estimator.sample_feed import regular_times

    arrival = np.array([0.0, 0.010, 0.035, 0.035, 0.035, 0.050, 0.2])
    t = regular_times(arrival, 0.01, 0.03)
    assert np.allclose(t, [0.0, 0.010, 0.020, 0.030, 0.035, 0.045, 0.17])
    assert np.all(t <= arrival) and np.all(arrival - t <= 0.03 + 1e-12)


def test_regular_times_find_the_grid_again_after_a_lost_sample():
    """A sample lost on the way (a corrupt frame) shifts the slots of the next ones a period
    early; within the clock's window the grid is found again, and a burst after a stall of the
    loop (samples late, none lost) is put back on the grid without such a shift."""
    from gyrohost.estimator.sample_feed import RegularClock, regular_times

    rng = np.random.default_rng(3)
    taken = 0.0037 + 0.01 * np.arange(400)
    delay = 0.001 + rng.exponential(0.002, taken.size)
    arrival = taken + delay
    arrival[250:252] = arrival[252]  # a 20 ms stall: two samples arrive with the third
    keep = np.ones(taken.size, bool)
    keep[100] = False  # lost
    t = regular_times(arrival[keep], 0.01, 0.03)
    # the grid the clock finds lies the smallest delay (so far) after the samples
    err = t - taken[keep] - np.min(delay)
    window = RegularClock.WINDOW
    assert np.max(np.abs(err[30:100])) < 1e-5
    assert np.allclose(err[100 : 100 + window - 5], -0.01, atol=1e-5)  # the lost one's slot
    assert np.max(np.abs(err[100 + window + 5 :])) < 1e-5  # found again, the burst included
    assert np.all(t <= arrival[keep] + 1e-12)


def test_replay_scores_a_realtime_run_against_its_truth(realtime_run, tmp_path):
    """A log with the simulated rig's truth: the replay's summary has the NEES of its own
    estimates against the truth at their times (at least one per truth interval within the
    estimate's span or per estimate, whichever is sparser; at most one per estimate), as the
    run's has. The same run replayed with the IMU's mounting taken 0.1 rad off in roll, which
    the filter is told it knows to 0.1 mrad: it reads the IMU's roll as the structure's, an
    error hundreds of its sigmas wide, so its NEES is at least ten times the right one's."""
    meta = read_meta(realtime_run)
    right = tmp_path / "right"
    assert main(["replay", str(realtime_run), "-o", str(right)]) == 0
    nees = read_meta(right)["summary"]["nees"]
    truth = read_stream(realtime_run, "truth")
    estimate = read_stream(realtime_run, "estimate")
    within = (truth["t_s"] >= estimate["t_s"][0]) & (truth["t_s"] <= estimate["t_s"][-1])
    # 12 node coordinates less 4 bar lengths and the 3 of the translation; 4 wheels; 2 strings
    assert nees["dof"] == 5 + 4 + 2
    replayed = read_stream(right, "estimate")
    # one per truth interval or per estimate, whichever is sparser (the truth: every 5 ms step)
    sparser = min(np.count_nonzero(within), len(replayed))
    assert 0.9 * sparser <= nees["samples"] <= len(replayed)
    assert np.isfinite(nees["mean"]) and nees["node_error_rms_m"] < 0.01
    turned = dict(meta["estimator"], imu_mounting_rpy_rad=[0.1, 0.0, 0.0])
    turned["imu_mounting_cov_rad2"] = [[1e-8, 0, 0], [0, 1e-8, 0], [0, 0, 1e-8]]
    lines = ["[estimator]"] + [f"{k} = {_toml(v)}" for k, v in turned.items()]
    (tmp_path / "turned.toml").write_text("\n".join(lines) + "\n")
    wrong = tmp_path / "wrong"
    argv = ["replay", str(realtime_run), "-o", str(wrong)]
    assert main([*argv, "--estimator", str(tmp_path / "turned.toml")]) == 0
    assert read_meta(wrong)["summary"]["nees"]["mean"] > 10 * nees["mean"]


def _toml(value) -> str:
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value)
