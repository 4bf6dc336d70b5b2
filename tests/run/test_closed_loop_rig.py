"""The D-bar tilt maneuver closed loop on the simulated rig, through ``gyrotens run``: the
re-planner runs from the EKF's estimate on its grid, every plan is accepted and logged, and the
run ends in the safe state. How much nearer closed loop lands than open loop on a truth with
heavier wheels is a study (``python -m studies rig_sil``), not a test: a real-time run's
landing error depends on the machine's timing."""

import numpy as np

from gyrohost.cli import main
from gyrohost.control.maneuver import Target
from gyrohost.run.log import read_meta, read_stream


def test_closed_loop_replans_on_its_grid_and_ends_safe(tmp_path):
    out = tmp_path / "closed"
    argv = ["run", "--sim", "--target-tilt", "-0.3", "--closed-loop", "-o", str(out)]
    assert main(argv) == 0
    replans = read_stream(out, "replan")
    assert len(replans) >= 10 and np.all(replans["accepted"] == 1)  # 1 first plan + re-plans
    # on the re-planning grid: at most one plan per period (a late one uses up its period, the
    # next comes at the next grid point, so two plans may stand closer than a period)
    slots = np.floor((replans["schedule_t_s"] - replans["schedule_t_s"][0]) / Target.period_s)
    assert np.all(np.diff(slots) >= 1), replans["schedule_t_s"]
    meta = read_meta(out)
    assert meta["target"]["closed_loop"] and meta["target"]["tilt_rad"] == -0.3
    assert meta["summary"]["maneuver"]["replans"] == len(replans) - 1
    assert meta["summary"]["reason"] == "completed"


def test_attitude_closed_loop_replans_within_the_limits_and_logs_its_landing(tmp_path):
    """Strings only: on the simulated rig (speed-controlled wheels, whose changes do not turn
    its truth) the D-bar turns about its momentum, its pitch axis."""
    from gyrohost.config import load_rig_config
    from gyrohost.resources import shipped

    out = tmp_path / "attitude"
    argv = ["run", "--sim", "--target-attitude", "0,-10,0", "--strings-only", "--closed-loop",
            "--replan-thread", "-o", str(out)]  # fmt: skip
    assert main(argv) == 0
    replans = read_stream(out, "replan")
    assert len(replans) >= 10 and replans["accepted"][0] == 1
    assert np.isnan(replans["tilt_rad"]).all() and np.isfinite(replans["error_rad"]).all()
    meta = read_meta(out)
    summary = meta["summary"]
    assert meta["target"]["attitude_rpy_rad"] == [0.0, float(np.radians(-10.0)), 0.0]
    assert meta["target"]["mode"] == "strings" and meta["target"]["knots"] == 8
    assert summary["maneuver"]["replans"] == len(replans) - 1
    assert summary["attitude_end_truth_error_rad"] >= 0.0
    command = read_stream(out, "command")
    for servo in load_rig_config(shipped("config", "sim-rig")).servos.servo:
        rest = np.asarray(command[f"{servo.string}_rest_m"], float)
        assert servo.min_length_m <= rest.min() and rest.max() <= servo.max_length_m
