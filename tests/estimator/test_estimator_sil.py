"""The filter on the rig's own truth model and IMU emulator (in process, simulated clock): a
short software-in-the-loop check; the 20-run Monte Carlo is
``python -m gyrohost.sil.scoring``."""

from pathlib import Path

import numpy as np
import pytest

from gyrohost.config import load_rig_config
from gyrohost.resources import shipped
from gyrohost.sil.scoring import RIG_MODEL_KEYS, score_rig_model_run
from gyrohost.simrig.config import sim_config

CONFIG = shipped("config", "sim-rig")


def test_filter_tracks_the_rig_truth_model():
    result = score_rig_model_run(load_rig_config(CONFIG), seed=3, duration_s=1.2,
                                 overrides=RIG_MODEL_KEYS)  # fmt: skip
    late = result.t_s >= 0.2
    assert np.degrees(result.tilt_rad).max() < 0.2
    assert result.nees_dof == 28  # with the accelerometer's bias a state (3)
    assert np.mean(result.nees[late]) < 2.0 * result.nees_dof
    for source in ("imu_rate", "imu_angle", "servos"):
        _, nis, dof = result.nis[source]
        assert 0.3 * dof[0] < np.mean(nis) < 2.0 * dof[0], source


def test_filter_follows_the_truth_as_the_run_loop_feeds_it():
    """The run loop's timing (arrival stamps on the IMU's grid, ticks late, servo reads late):
    one seed, 3 s. A consistent filter's time-averaged NEES has the dof as its expectation and
    one seed's spreads by tens of percent around it; a filter the loop's timing breaks runs to
    many times the dof. 3 x dof tells the two apart on any CPU; the consistency itself is the
    study's (``python -m studies estimator_effects``)."""
    from gyrohost.sil.effects import CASES, score_with_effects

    result = score_with_effects(load_rig_config(CONFIG), 1, CASES["loop-fixed"], 3.0)
    late = result.t_s >= 0.2
    assert np.all(np.isfinite(result.nees))
    assert np.mean(result.nees[late]) < 3.0 * result.nees_dof
    assert np.degrees(np.abs(result.tilt_rad)).max() < 0.3


def test_truth_runs_its_own_scene_and_mounting(tmp_path):
    """``[sim.truth] scene`` and ``imu_rotation_deg``: the truth (wheels 30 % heavier) moves
    otherwise than under the host's scene, which the host's commands and model keep; the true
    sensor axes are the frame's turned by the rotation."""
    from gyrohost.geometry import rotation_zyx
    from gyrohost.sil.scoring import rig_model_run
    from gyrohost.simrig.config import with_sim_keys, with_truth_scene

    scene = Path(shipped("scene", "dbar-gyro")).read_text()
    J3 = 1.3 * 0.5 * 0.05 * 0.031**2
    (tmp_path / "heavy.toml").write_text(scene.replace("spin = ", f"J3 = {J3!r}, spin = "))
    config = load_rig_config(CONFIG)
    other = with_truth_scene(config, tmp_path / "heavy.toml")
    rotation_deg = (1.0, -2.0, 3.0)
    other = with_sim_keys(other, "truth", imu_rotation_deg=list(rotation_deg))
    model, data, x, R, *_ = rig_model_run(config, 1, 0.5)
    model_o, data_o, x_o, R_o, *_ = rig_model_run(other, 1, 0.5)
    assert model_o.J3[0] == model.J3[0]  # the host's scene
    assert np.array_equal(data_o["command"], data["command"])
    L = model.layout
    assert np.abs(x_o[-1, L.q] - x[-1, L.q]).max() > 1e-5  # m
    turn = rotation_zyx(*np.radians(rotation_deg))
    np.testing.assert_allclose(R_o[0], R[0] @ turn, atol=1e-12)  # at the same initial state


def test_a_schedule_is_played_with_its_wheel_speeds():
    """``rig_model_run(schedule=...)``: the host commands the schedule's rest lengths and wheel
    speeds (the scene's are not played), and the board takes the wheels to a step within its
    ramp (100 rad/s^2) while the truth's spins follow."""
    from gyrohost.control.schedule import Schedule
    from gyrohost.estimator import streams
    from gyrohost.sil.scoring import rig_model_run

    config = load_rig_config(CONFIG)
    w0 = 74.87462492 * np.array([1.0, -1.0, -1.0, 1.0])
    t = np.array([0.0, 0.2, 0.25, 0.6, 1.0])
    s13 = np.array([0.43105, 0.43105, 0.43105, 0.41, 0.41])
    s24 = np.sqrt(4 * 0.3048**2 - s13**2)
    factor = np.array([1.0, 1.0, 1.1, 1.1, 1.1])
    schedule = Schedule(("s13", "s24"), t, np.column_stack([s13, s24]), "test",
                        ("b12", "b23", "b34", "b41"), np.outer(factor, w0))  # fmt: skip
    model, data, x, _, _, dt_s = rig_model_run(config, 1, 1.0, schedule=schedule)
    command = data[streams.COMMAND]
    np.testing.assert_allclose(command["s13_rest_m"], np.interp(command["t_s"], t, s13))
    spins = np.column_stack([command[c] for c in streams.wheel_command_columns(4)])
    np.testing.assert_allclose(spins, np.outer(np.interp(command["t_s"], t, factor), w0))
    true = x[:, 2 * 3 * model.layout.m : 2 * 3 * model.layout.m + 4]
    k_step = int(round(0.2 / dt_s))
    error = 5.0 * sim_config(config).wheels.speed_error_std_rad_s  # the speed loop's, 5 std
    np.testing.assert_allclose(true[k_step], w0, atol=error)  # held until the step
    np.testing.assert_allclose(true[-1], 1.1 * w0, atol=0.05 + error)  # ramped within 0.5 s
    reported = data[streams.WHEELS]
    late = reported["t_s"] > 0.8
    assert np.abs(reported["omega_0_rad_s"][late] - 1.1 * w0[0]).max() < 0.5


def test_file_keys_reach_the_simulated_clock_filter_and_the_rig_s_do_not(tmp_path):
    """``--estimator``'s keys override the SIL's own: a servo noise of 10 mm (the SIL's: 4.4 um)
    and an angle noise of 1 rad make their NIS vanish in the filter that runs. The rig's own
    ``[estimator]`` table (its real-time figures) does not reach the simulated clock."""
    from gyrohost.sil.scoring import sil_keys, sil_results

    config = load_rig_config(CONFIG)
    extra = tmp_path / "estimator.toml"
    extra.write_text("[estimator]\nservo_length_std_m = 0.01\nimu_angle_std_rad = 1.0\n")
    keys = sil_keys(extra)
    assert keys["servo_length_std_m"] == 0.01 and keys["imu_angle_std_rad"] == 1.0
    assert keys["servo_time_std_s"] == RIG_MODEL_KEYS["servo_time_std_s"]  # not overridden
    assert config.estimator["servo_time_std_s"] != RIG_MODEL_KEYS["servo_time_std_s"]
    (result,) = sil_results(config, runs=1, duration_s=0.3, estimator=extra)
    for source in ("servos", "imu_angle"):
        _, nis, dof = result.nis[source]
        assert len(nis) > 0 and np.mean(nis) < 1e-3 * dof[0], source
    _, nis, dof = result.nis["imu_rate"]  # the SIL's own figure
    assert np.mean(nis) > 0.1 * dof[0]


def test_a_bad_file_key_names_the_file(tmp_path):
    from gyrohost.estimator.errors import EstimatorConfigError
    from gyrohost.sil.scoring import sil_keys

    extra = tmp_path / "estimator.toml"
    extra.write_text("[estimator]\nservo_length_sd_m = 0.01\n")
    with pytest.raises(EstimatorConfigError, match=r"estimator\.toml.*servo_length_sd_m"):
        sil_keys(extra)


def test_score_only_without_recorded_runs_says_what_it_reads(tmp_path, capsys):
    from gyrohost.cli import main

    code = main(["sil", "--realtime", "--score-only", "--runs", "2", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2
    assert "run01: not a log folder" in err and "--score-only scores the runs" in err


def test_score_only_scores_every_run_recorded_in_a_row(tmp_path, capsys):
    from gyrohost.cli import main
    from gyrohost.sil.scoring import recorded_runs

    for k in (1, 2, 4):  # run03 missing: run04 is no run of this series
        (tmp_path / f"run{k:02d}").mkdir()
        (tmp_path / f"run{k:02d}" / "meta.json").write_text("{}")
    assert recorded_runs(tmp_path) == 2
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["sil", "--realtime", "--score-only", "--out", str(empty)]) == 2
    assert f"{empty}: no recorded runs to score" in capsys.readouterr().err


@pytest.mark.parametrize("completed", [True, False])
def test_a_real_time_run_whose_filter_diverged_is_scored(tmp_path, monkeypatch, completed):
    """A run whose estimator diverged completes with exit status 1 (a nominal scene against
    another truth): the SIL scores it, for its NEES is the figure asked for; a run that
    stopped before its schedule ended is an error naming it."""
    import gyrohost.run
    from gyrohost.run.settings import RunResult
    from gyrohost.sil.errors import SilError
    from gyrohost.sil.scoring import record_run

    reason = "completed" if completed else "wheel board silent"
    ended = RunResult(completed, reason, 1, tmp_path)
    monkeypatch.setattr(gyrohost.run, "run_simulated", lambda *args, **kwargs: ended)
    config = load_rig_config(CONFIG)
    if completed:
        assert record_run(config, 1, tmp_path, 0.5) == tmp_path
    else:
        with pytest.raises(SilError, match=f"{tmp_path}: the run stopped: wheel board silent"):
            record_run(config, 1, tmp_path, 0.5)
