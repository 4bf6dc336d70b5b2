"""Identification on the real-time simulated rig through the commands a lab uses: a run of the
identification schedule's first part against a truth that differs from the host's scene (J3 x
1.3, string stiffness x 1.25, damping x 0.7, the IMU turned (3, -1.7, 1.1) degrees; the bars
weighed), ``gyrotens identify`` of its log, and a run with the identified scene and overlay."""

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from gyrohost.cli import main
from gyrohost.config import load_rig_config
from gyrohost.control.schedule import Schedule, load_schedule
from gyrohost.experiments.identify_check import coverage_lines
from gyrohost.experiments.identify_rig import (
    IMU_ROTATION_DEG,
    estimator_figures,
    identified_errors,
    truth_kept_overlay,
    write_rig_files,
)
from gyrohost.resources import resolve
from gyrohost.run.log import FORMAT

FIRST_S = 11.3  # s of the identify schedule: its first three blocks of pulls, ending at rest


def first_part(path):
    """The identify schedule up to ``FIRST_S``, written to ``path``."""
    s = load_schedule(resolve("schedule", "identify"))
    keep = s.t <= FIRST_S
    cut = Schedule(s.names, s.t[keep], s.rest_length[keep], "identify-first", s.wheels,
                   s.wheel_speed[keep], s.purpose)  # fmt: skip
    return cut.save(path)


YAW_BOUND_DEG = 0.5
"""The identified mounting's yaw is this near the truth's at most, degrees (below)."""
RECORDINGS = 3
"""Recordings at most, until one kept real time (below)."""


def record(tmp_path, rig, schedule, capsys) -> Path:
    """The identification run's log, recorded again while the simulated rig's
    truth did not keep real time. A CPU too loaded for it (other processes of a shared CI
    machine) records a truth whose physics lags its stamps by tens of ms and varies; the
    identification reads that as a mounting turned by tenths of a degree (docs/identification.md):
    such a log is no test of the identification, which the rig's own step timing tells."""
    tried = []
    for k in range(RECORDINGS):
        log = tmp_path / f"ident-run-{k}"
        status = main(["run", *rig, "--schedule", str(schedule), "-o", str(log)])
        summary = json.loads((log / "meta.json").read_text())["summary"]
        assert summary["reason"] == "completed"
        # the nominal EKF may diverge against this truth, which an identification run does not
        # count against it: the log is what it is for
        assert summary["schedule_purpose"] == "identification"
        assert not summary["estimator"]["required"]
        assert status == 0, summary["estimator"]["why"]
        out = capsys.readouterr()
        assert f"next: gyrotens identify {log} -o ident.toml --config {rig[2]}" in out.out
        if summary["rig_real_time"]["kept"]:
            return log
        assert "did not keep real time" in out.err  # and the run says so
        tried.append(summary["rig_real_time"])
    raise AssertionError(f"no recording of {RECORDINGS} kept real time: {tried}")


def test_rig_log_identified_then_run_with_the_result(tmp_path, capsys):
    config, truth = write_rig_files(tmp_path, seed=1)
    rig = ["--sim", "--config", str(config), "--truth-scene", str(truth)]
    log = record(tmp_path, rig, first_part(tmp_path / "first.toml"), capsys)
    ident, overlay = tmp_path / "ident.toml", tmp_path / "overlay.toml"
    argv = ["identify", str(log), "-o", str(ident), "--config", str(config)]
    assert main([*argv, "--overlay", str(overlay)]) == 0
    assert f"--overlay {overlay} --scene {ident}" in capsys.readouterr().out
    errors = identified_errors(ident, overlay)
    assert abs(errors["J3"][0]) < 0.03, errors
    assert 0.0 < errors["J3"][1] < 0.03, errors  # the reported 1-sigma, read back
    for axis in ("roll", "pitch"):
        assert abs(errors[f"mounting.{axis}_deg"][0]) < 0.3, errors
    # the output error's yaw on such logs: within 0.21 degrees in 21 recordings, 0.35 in one,
    # outside the acceptance's 0.3 (docs/identification.md, "The output error's yaw on the
    # real-time rig"); the filter's fit holds the acceptance (test_filter_fit)
    assert abs(errors["mounting.yaw_deg"][0]) < YAW_BOUND_DEG, errors
    again = tmp_path / "with-ident"
    kept = truth_kept_overlay(overlay, tmp_path / "run-overlay.toml")
    argv = [*rig, "--overlay", str(kept), "--scene", str(ident), "-o", str(again)]
    main(["run", *argv])
    meta = json.loads((again / "meta.json").read_text())
    assert meta["summary"]["reason"] == "completed"
    # the truth's IMU stays where it was, so the estimator on the identified rig follows it
    np.testing.assert_allclose(meta["rig_config"]["sim"]["truth"]["imu_rotation_deg"], 0, atol=0.3)
    assert not meta["summary"]["estimator"]["diverged"], meta["summary"]["estimator"]["why"]
    mounting = tomllib.loads(overlay.read_text())["imu"]["mounting_rpy_rad"]
    np.testing.assert_allclose(meta["estimator"]["imu_mounting_rpy_rad"], mounting)


def test_rig_files_seed_every_emulator_and_set_the_wheels_error(tmp_path):
    config, truth = write_rig_files(tmp_path, seed=4, speed_error_rad_s=0.01)
    rig = load_rig_config(config)
    assert (rig.sim.imu.seed, rig.sim.wheels.seed, rig.sim.servos.seed) == (4, 4, 4)
    assert rig.sim.wheels.speed_error_std_rad_s == 0.01
    assert rig.sim.truth.imu_rotation_deg == IMU_ROTATION_DEG
    assert Path(rig.scene_path).name == "weighed.toml"
    assert tomllib.loads(truth.read_text())["strings"][0]["damping"] == pytest.approx(1.4)
    (tmp_path / "exact").mkdir()
    exact = load_rig_config(write_rig_files(tmp_path / "exact", seed=1)[0])
    assert exact.sim.wheels.speed_error_std_rad_s == 0.0


def test_estimator_figures_read_the_runs_summary(tmp_path):
    nees = {"mean": 14.2, "dof": 14, "inside": 0.93, "sample_bounds95": [5.6, 26.1]}
    wheels = {"mean": 2.0, "dof": 4, "bounds95": [3, 5]}
    summary = {
        "estimator": {"nees": nees, "nis": {"wheels": wheels}},
        "tilt_end_estimate_rad": 0.51,
        "tilt_end_truth_rad": 0.5,
    }
    (tmp_path / "meta.json").write_text(json.dumps({"format": FORMAT, "summary": summary}))
    figures = estimator_figures(tmp_path)
    assert figures["nees"] == (14.2, 0.93) and figures["wheels"] == (2.0, False)
    assert figures["tilt_end_error_deg"] == pytest.approx(np.degrees(0.01))


def test_the_coverage_table_counts_errors_within_one_and_two_sigmas():
    rows = [{"J3": (e, 0.01)} for e in (0.005, -0.015, 0.025)] + [{"damping": (0.1, 0.2)}]
    lines = coverage_lines(rows, "relative")
    j3 = next(line for line in lines if line.startswith("J3")).split()
    assert j3[1:] == ["0.0150", "0.0250", "0.0100", "33%", "67%"]
    assert next(line for line in lines if line.startswith("damping")).endswith("100%        100%")
    assert lines[-1] == "(relative; expected coverage 68 % and 95 %, 4 seeds)"
