"""A scene without the D-bar runs on the simulated rig end to end (node positions, the estimate
and its covariance, its body frame's attitude, no tilt), and the estimator takes its own
configuration from the rig configuration's ``[estimator]`` table, overridden by
``--estimator``."""

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyrohost.cli import main
from gyrohost.config import load_rig_config
from gyrohost.estimator import EstimatorConfigError
from gyrohost.estimator.config import for_rig
from gyrohost.resources import shipped
from gyrohost.run.log import read_meta, read_stream
from gyrohost.run.streams import BODY_ATTITUDE

PRISM_CONFIG = shipped("config", "prism-sim-rig")
PRISM_SCHEDULE = shipped("schedule", "prism-s7")
SIM_CONFIG = shipped("config", "sim-rig")
LAB_CONFIG = shipped("config", "lab-rig")


def test_the_prism_runs_end_to_end_with_nodes_and_estimate_and_no_tilt(tmp_path, capsys):
    log = tmp_path / "log"
    argv = ["run", "--config", str(PRISM_CONFIG), "--sim", "--schedule", str(PRISM_SCHEDULE)]
    assert main([*argv, "-o", str(log)]) == 0, capsys.readouterr().err
    meta = read_meta(log)
    assert meta["summary"]["completed"]
    assert "tilt_end_estimate_rad" not in meta["summary"]
    settled = meta["summary"]["attitude_settled"]  # the body frame's, estimate and truth
    assert np.linalg.norm(settled["truth"]["quaternion"]) == pytest.approx(1.0, abs=1e-12)
    assert 0.0 <= settled["error_rad"] < np.pi
    nodes, truth = read_stream(log, "nodes"), read_stream(log, "truth")
    assert "tilt_rad" not in nodes.dtype.names and "tilt_rad" not in truth.dtype.names
    assert {"b1_z_m", "t3_z_m"} <= set(nodes.dtype.names)
    assert len(nodes) > 20 and np.all(np.isfinite(nodes["t2_z_m"]))
    for stream in (nodes, truth):  # the [attitude] frame's: a unit quaternion and its angles
        q = np.column_stack([stream[c] for c in BODY_ATTITUDE[:4]])
        rpy = np.column_stack([stream[c] for c in BODY_ATTITUDE[4:]])
        assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
        angles = Rotation.from_quat(q, scalar_first=True).as_euler("ZYX")[:, ::-1]
        assert np.allclose(rpy, angles, atol=1e-9)
    estimate = read_stream(log, "estimate")
    stds = [c for c in estimate.dtype.names if c.startswith("std_")]
    assert stds and np.all(np.isfinite(estimate[stds[0]]))
    assert truth["s7_rest_m"][-1] < truth["s7_rest_m"][0] - 0.015  # the servo wound s7 in
    assert meta["estimator"]["imu_frame_nodes"] == ["b1", "t1", "b2"]
    assert main(["plot", str(log)]) == 0
    written = sorted(p.name for p in (log / "plots").iterdir())
    assert "fig7-nodes.png" in written and "attitude.png" in written
    assert "body-attitude.png" in written
    assert "fig8-node-z.png" not in written  # the D-bar's plane nodes only


def test_a_preset_of_the_dbar_is_refused_for_the_prism_naming_the_nodes(capsys):
    assert main(["run", "--config", str(PRISM_CONFIG), "--sim", "--schedule", "paper"]) == 2
    assert "preset 'paper' is for the D-bar (nodes n1, n2, n3, n4)" in capsys.readouterr().err


def _with_estimator_table(tmp_path, config: Path, table: str) -> Path:
    """A copy of ``config`` (its scene a shipped name) with its ``[estimator]`` table replaced."""
    text = config.read_text()
    path = tmp_path / "rig.toml"
    path.write_text(text.split("[estimator]")[0] + "[estimator]\n" + table)
    return path


def test_the_estimator_table_is_used_and_the_file_overrides_it(tmp_path):
    rig = load_rig_config(_with_estimator_table(tmp_path, LAB_CONFIG, "imu_rate_std_rad_s = 4e-3"))
    assert for_rig(rig).imu_rate_std_rad_s == 4e-3
    override = tmp_path / "ekf.toml"
    override.write_text("[estimator]\nimu_rate_std_rad_s = 7e-3\n")
    assert for_rig(rig, override).imu_rate_std_rad_s == 7e-3
    assert for_rig(rig, override).imu_frame_nodes == ("n1", "n3", "n2")  # the D-bar's
    lab = load_rig_config(LAB_CONFIG)  # its own figures
    assert for_rig(lab).imu_rate_std_rad_s == lab.estimator["imu_rate_std_rad_s"]


def test_a_bad_estimator_key_or_attachment_is_refused_naming_it(tmp_path, capsys):
    path = _with_estimator_table(tmp_path, LAB_CONFIG, "imu_rate_std_rad = 4e-3")
    with pytest.raises(EstimatorConfigError, match=r"rig.toml: \[estimator\]: unknown estimator"):
        for_rig(load_rig_config(path))
    assert main(["run", "--config", str(path), "-o", str(tmp_path / "log")]) == 2
    assert "unknown estimator key 'imu_rate_std_rad'" in capsys.readouterr().err
    assert not (tmp_path / "log").exists()  # refused before anything was opened
    prism = ["--scene", str(shipped("scene", "prism-gyro")), "--schedule", str(PRISM_SCHEDULE)]
    assert main(["run", "--config", str(LAB_CONFIG), *prism, "-o", str(tmp_path / "log")]) == 2
    assert "estimator key 'imu_frame_nodes': node 'n1' is not in scene" in capsys.readouterr().err
    assert not (tmp_path / "log").exists()


def test_the_estimator_table_is_checked_like_the_rest_of_the_rig_configuration(tmp_path):
    path = _with_estimator_table(tmp_path, LAB_CONFIG, 'imu_rate_std_rad_s = "small"')
    with pytest.raises(EstimatorConfigError, match=r"'imu_rate_std_rad_s' must be a finite number"):
        for_rig(load_rig_config(path))
    path = _with_estimator_table(tmp_path, LAB_CONFIG, "imu_period_s = 2.0")
    with pytest.raises(EstimatorConfigError, match=r"estimator key 'imu_period_s' is 2.0"):
        for_rig(load_rig_config(path))


def test_the_table_and_the_estimator_file_reach_the_logged_ekf_configuration(tmp_path, capsys):
    table = 'imu_frame_nodes = ["b1", "t1", "b2"]\nwheel_speed_std_rad_s = 0.75\n'
    table += "servo_length_std_m = 2e-3\n"
    config = _with_estimator_table(tmp_path, PRISM_CONFIG, table)
    override = tmp_path / "ekf.toml"
    override.write_text("[estimator]\nservo_length_std_m = 3e-3\n")
    log = tmp_path / "log"
    argv = ["run", "--config", str(config), "--sim", "--schedule", str(PRISM_SCHEDULE)]
    assert main([*argv, "--estimator", str(override), "-o", str(log)]) == 0, capsys.readouterr()
    estimator = read_meta(log)["estimator"]
    assert estimator["wheel_speed_std_rad_s"] == 0.75  # from the table
    assert estimator["servo_length_std_m"] == 3e-3  # the file over the table
    assert estimator["imu_frame_nodes"] == ["b1", "t1", "b2"]  # from the table
