"""Identification by the filter's prediction error on the simulated rig's models, whose wheels
err from their setpoints (the speed loop's error, 0.01 rad/s): the truth of
``gyrohost.ident.simcheck`` (J3 x 1.3, stiffness x 1.25, damping x 0.7, IMU 3 deg off). How near
the fit comes over seeds, and how often its sigmas cover the error, is a study
(``python -m studies identify_check --method filter``); here the fit's machinery."""

import os
import signal
import subprocess
import sys
import threading
import time
import warnings
from dataclasses import replace
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pytest

from gyrohost.cli import main
from gyrohost.ident import filter_fit
from gyrohost.ident.errors import IdentDataError, ParamsError
from gyrohost.ident.fit import FAILED_RESIDUAL
from gyrohost.ident.params import parameters
from gyrohost.ident.simcheck import (
    record_log,
    write_rigs,
)

SPEED_ERROR_RAD_S = 0.01


def test_the_window_is_the_logs_phases_cut_by_until(tmp_path):
    _, truth = write_rigs(tmp_path, 1.5)
    log = record_log(truth, 2, tmp_path / "log")
    whole = filter_fit.load(log)
    cut = filter_fit.load(log, until_s=0.5)
    t = whole.data["imu"]["t_s"]
    assert t[0] >= 0.0 and t[-1] > 1.4
    assert cut.data["imu"]["t_s"][-1] < 0.5 <= cut.data["imu"]["t_s"][-1] + 0.011
    with pytest.raises(IdentDataError, match="fewer than two IMU samples"):
        filter_fit.load(log, until_s=0.005)


NODE_PSD_M2_S3 = 3e-8


def _problem(tmp_path, workers=1, groups=("J3",)):
    from gyrohost.config import load_rig_config
    from gyrohost.estimator.config import for_rig
    from gyrotensegrity import load_scene

    tmp_path.mkdir(exist_ok=True)
    nominal, truth = write_rigs(tmp_path, 1.0)
    log = record_log(truth, 3, tmp_path / "log")
    config = load_rig_config(nominal)
    scene, est = load_scene(config.scene_path), for_rig(config)
    if "process-noise" in groups:  # a node noise for the factor to scale: the sim keys take none
        est = replace(est, accel_psd_m2_s3=NODE_PSD_M2_S3)
    params = parameters(scene, config, list(groups), est.servo_lag_s, 1, est, True)
    return filter_fit.FilterProblem(scene, config, est, params, [filter_fit.load(log)], workers)


def test_process_noise_on_a_filter_without_node_noise_is_refused(tmp_path):
    """A filter that takes no node noise: a factor on none leaves none, so the group, asked
    for, is refused by name."""
    from gyrohost.config import load_rig_config
    from gyrohost.estimator.config import for_rig
    from gyrotensegrity import load_scene

    nominal, _ = write_rigs(tmp_path, 1.0)
    config = load_rig_config(nominal)
    scene = load_scene(config.scene_path)
    est = replace(for_rig(config), accel_psd_m2_s3=0.0)
    with pytest.raises(ParamsError, match=r"process-noise scales .*accel_psd_m2_s3, which is 0"):
        parameters(scene, config, ["process-noise"], est.servo_lag_s, 1, est, True)


def test_the_likelihood_is_lowest_near_the_imus_true_latency(tmp_path):
    """The nominal rig with an IMU that stamps its samples 15 ms after taking them, the filter
    tuned to the rig's models (:func:`gyrohost.ident.simcheck.identify_filter`'s): fused at
    that latency the recording is explained better than at none or at twice it, by far more
    than one unit of log-likelihood (the likelihood can fit the latency; a 1 s recording, one
    seed: a check of the cost, not of a fit)."""
    from gyrohost.config import load_rig_config
    from gyrohost.estimator.config import config_from_dict
    from gyrohost.sil.emulator_keys import emulator_keys
    from gyrohost.sil.scoring import RIG_MODEL_KEYS
    from gyrotensegrity import load_scene

    true_s = 0.015
    nominal, _ = write_rigs(tmp_path, 1.0)
    truth = tmp_path / "latency-rig.toml"
    truth.write_text(nominal.read_text() + f"\n[sim.truth]\nimu_latency_s = {true_s}\n")
    log = record_log(truth, 3, tmp_path / "log")
    config = load_rig_config(nominal)
    scene = load_scene(config.scene_path)
    est = config_from_dict({**emulator_keys(config), **RIG_MODEL_KEYS})
    params = parameters(scene, config, ["imu-latency"], est.servo_lag_s, 1, est, True)
    problem = filter_fit.FilterProblem(scene, config, est, params, [filter_fit.load(log)])

    def cost(latency_s):
        r = problem(np.array([latency_s - params[0].nominal]))
        return 0.5 * float(r @ r)

    at_truth = cost(true_s)
    assert at_truth < cost(0.0) - 10.0 and at_truth < cost(2 * true_s) - 10.0


def test_the_filter_fit_runs_the_filter_at_the_fitted_latency_and_noise(tmp_path, monkeypatch):
    """The filter groups change the filter the fit runs: its latency (absolute, s) and its
    node-acceleration noise (a log factor)."""
    problem = _problem(tmp_path, groups=("imu-latency", "process-noise"))
    seen = []
    monkeypatch.setattr(
        filter_fit, "_run", lambda model, est, rec, data: seen.append(est) or ([], None)
    )
    latency, psd = (p.nominal for p in problem.params)
    problem.runs(np.array([0.004, np.log(3.0)]))
    assert seen[0].imu_latency_s == pytest.approx(latency + 0.004)
    assert seen[0].accel_psd_m2_s3 == pytest.approx(3.0 * psd)


def test_the_residuals_are_the_innovations_likelihood(tmp_path):
    """Each innovation's whitened components and then the square root of its spread: half
    their squares sum to the NIS and log det S - log det R, the negative log-likelihood up to
    a constant; the noise variance is the whitened components' alone."""
    problem = _problem(tmp_path)
    r = problem(np.zeros(1))
    run = [i for recording, _ in problem.runs(np.zeros(1)) for i in recording]
    assert len(r) == sum(len(i.whitened) + 1 for i in run)
    nis, spread = sum(i.nis for i in run), sum(i.spread for i in run)
    assert spread > 0.0 and r @ r == pytest.approx(nis + spread, rel=1e-12)
    assert problem.residual_variance(r, 1) == pytest.approx(nis / (len(r) - len(run) - 1))


def test_a_batch_in_worker_processes_is_the_runs_one_by_one(tmp_path):
    """The Jacobian's columns run in other processes, each with its own copy of the problem:
    the same residuals to the last bit, every run counted."""
    thetas = [np.array([v]) for v in (0.05, -0.05, 0.1)]
    serial = _problem(tmp_path / "one")
    expected = [serial(t) for t in thetas]
    parallel = _problem(tmp_path / "two", workers=2)
    parallel(np.zeros(1))  # the first run sets the residuals' length
    try:
        got = parallel.batch(thetas)
    finally:
        parallel.close()
    for e, g in zip(expected, got, strict=True):
        np.testing.assert_array_equal(g, e)
    assert parallel.simulations == 1 + len(thetas)


UNGUARDED_SCRIPT = """
import sys
from pathlib import Path
import numpy as np
from gyrohost.config import load_rig_config
from gyrohost.estimator.config import for_rig
from gyrohost.ident.simcheck import record_log, write_rigs
from gyrohost.ident import filter_fit
from gyrohost.ident.errors import IdentDataError, ParamsError
from gyrohost.ident.params import parameters
from gyrotensegrity import load_scene

root = Path(sys.argv[1])
nominal, truth = write_rigs(root, 0.3)
config = load_rig_config(nominal)
scene, est = load_scene(config.scene_path), for_rig(config)
params = parameters(scene, config, ["J3"], est.servo_lag_s)
log = record_log(truth, 1, root / "log")
problem = filter_fit.FilterProblem(scene, config, est, params, [filter_fit.load(log)], 2)
problem(np.zeros(1))
problem.batch([np.ones(1)])
"""


def test_a_script_without_the_main_guard_gets_an_error_not_a_hang(tmp_path):
    """Spawned workers import the caller's script first; without the guard they die at
    start-up, which must end the fit with an error that says why."""
    script = tmp_path / "unguarded.py"
    script.write_text(UNGUARDED_SCRIPT)
    (tmp_path / "rigs").mkdir()
    env = dict(os.environ, TMPDIR=str(tmp_path))  # the dying workers' own problem files
    done = subprocess.run(
        [sys.executable, str(script), str(tmp_path / "rigs")],
        capture_output=True, text=True, timeout=120, cwd=tmp_path, env=env,
    )  # fmt: skip
    assert done.returncode != 0
    assert "FilterFitError" in done.stderr and "__name__" in done.stderr, done.stderr[-2000:]


@pytest.mark.parametrize("starting", [True, False], ids=["workers starting", "workers fitting"])
def test_ctrl_c_ends_a_fit_in_workers_quietly_and_leaves_nothing_behind(tmp_path, starting):
    """Ctrl-C reaches every process of the group: the command says it was interrupted (no
    worker's traceback, also while the workers are still importing), its workers end with it
    and their problem file is removed."""
    nominal, truth = write_rigs(tmp_path, 1.0)
    log = record_log(truth, 1, tmp_path / "log")
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    fit = subprocess.Popen(
        [sys.executable, "-m", "gyrohost.cli", "identify", str(log), "--config", str(nominal),
         "--method", "filter", "--workers", "2", "--params", "J3,mounting",
         "-o", str(tmp_path / "ident.toml")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
        env=dict(os.environ, TMPDIR=str(scratch)),
    )  # fmt: skip
    deadline = time.monotonic() + 60.0
    while not list(scratch.glob("gyrotens-filter-fit-*")) and time.monotonic() < deadline:
        time.sleep(0.05)
    if starting:  # the interrupt as soon as both workers exist, while they still import
        while len(_group(fit.pid)) < 3 and time.monotonic() < deadline:
            time.sleep(0.005)
    else:
        time.sleep(2.0)  # the workers spawned and fitting
    os.killpg(fit.pid, signal.SIGINT)
    _, err = fit.communicate(timeout=60)
    assert fit.returncode == 130 and "interrupted" in err, err[-2000:]
    assert "Traceback" not in err, err[-2000:]
    assert not list(scratch.glob("gyrotens-filter-fit-*"))
    deadline = time.monotonic() + 10.0
    while _group_alive(fit.pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _group_alive(fit.pid)


def _blocked_signals() -> int:
    """The calling thread's blocked-signal mask (Linux: /proc, for a spawned process)."""
    for line in Path("/proc/thread-self/status").read_text().splitlines():
        if line.startswith("SigBlk:"):
            return int(line.split()[1], 16)
    raise AssertionError("no SigBlk in /proc/thread-self/status")


def test_a_ctrl_c_while_workers_start_is_held_for_the_parent_and_kept_from_the_workers():
    """The race the group test above can only hit by chance: the interrupt arrives while the
    processes are being started. The parent gets it when the block ends, not lost; a process
    started in the block starts with it blocked, one started outside does not."""
    bit = 1 << (signal.SIGINT - 1)
    spawn = get_context("spawn")
    with pytest.raises(KeyboardInterrupt):
        with filter_fit._interrupts_held():
            signal.pthread_kill(threading.get_ident(), signal.SIGINT)
            pool_in_block = spawn.Pool(1)  # reached: the interrupt waits for the block's end
    with pool_in_block, spawn.Pool(1) as pool_outside:
        assert pool_in_block.apply(_blocked_signals) & bit
        assert not pool_outside.apply(_blocked_signals) & bit
    assert not _blocked_signals() & bit


def _group(pgid: int) -> list[int]:
    """The processes of the process group ``pgid`` (Linux: /proc)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue  # ended meanwhile
        if int(fields[2]) == pgid:  # after the name: state, ppid, pgrp
            found.append(int(stat.parent.name))
    return found


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def test_a_filter_that_breaks_is_refused_at_the_start_and_fenced_off_later(tmp_path, monkeypatch):
    """Where the filter breaks under a parameter vector the fit tried, the rest of the
    recording's residuals are a wall the optimiser backs off from (and the break is counted);
    under the nominal parameters, where the fit starts, it is an error naming them."""
    problem = _problem(tmp_path)
    whole = problem(np.zeros(1))
    run = filter_fit._run

    def breaks_halfway(model, est, rec, data):
        innovations, _ = run(model, est, rec, data)
        return innovations[: len(innovations) // 2], "t = 0.5 s: prediction failed"

    monkeypatch.setattr(filter_fit, "_run", breaks_halfway)
    broken = problem(np.array([0.1]))
    assert len(broken) == len(whole)
    half = np.flatnonzero(broken == FAILED_RESIDUAL)
    assert len(half) > 0.4 * len(whole) and half[-1] == len(whole) - 1
    assert len(problem.failures) == 1 and "J3" in problem.failures[0]

    fresh = _problem(tmp_path / "again")
    monkeypatch.setattr(filter_fit, "_run", breaks_halfway)
    with pytest.raises(filter_fit.FilterFitError, match="prediction failed.*J3"):
        fresh(np.zeros(1))


def test_a_noise_factor_beyond_floats_is_a_counted_break_not_a_crash(tmp_path, monkeypatch):
    """A trial step of the process-noise factor that overflows (where the likelihood is flat the
    solver may take one) is walled like any break, without warnings; so is a trial under which
    every run breaks before its first fusion (no innovation at all)."""
    problem = _problem(tmp_path, groups=("process-noise",))
    whole = problem(np.zeros(1))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        far = problem(np.array([1000.0]))
    assert not caught, [str(w.message) for w in caught]
    assert len(far) == len(whole) and np.any(far == FAILED_RESIDUAL)
    assert len(problem.failures) == 1 and "accel_psd inf" in problem.failures[0], problem.failures
    monkeypatch.setattr(filter_fit, "_run", lambda *args: ([], "t = 0 s: prediction failed"))
    nothing = problem(np.array([2.0]))
    assert len(nothing) == len(whole) and np.all(nothing == FAILED_RESIDUAL)
    assert len(problem.failures) == 2


def test_a_filter_diverging_far_out_is_a_counted_break_not_a_crash(tmp_path):
    """Strings 3000 times too stiff (e^8) make the prediction diverge, its substeps taken for
    the stiffness in the filter's model, until the bars' constraints are singular: a break the
    fit walls off and names, without warnings."""
    problem = _problem(tmp_path, groups=("stiffness",))
    problem(np.zeros(1))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        far = problem(np.array([8.0]))
    assert not caught, [str(w.message) for w in caught]
    assert np.any(far == FAILED_RESIDUAL)
    assert len(problem.failures) == 1 and "stiffness" in problem.failures[0], problem.failures


def test_cli_fits_by_the_filter_and_writes_scene_overlay_and_plot(tmp_path, capsys):
    nominal, truth = write_rigs(
        tmp_path, 1.5, weighed=True, speed_error_std_rad_s=SPEED_ERROR_RAD_S
    )
    log = record_log(truth, 2, tmp_path / "log")
    out = tmp_path / "ident" / "rig.toml"
    argv = ["identify", str(log), "-o", str(out), "--config", str(nominal), "--method", "filter"]
    assert main([*argv, "--params", "J3,mounting,gyro-bias", "--max-evaluations", "3"]) == 0
    text = capsys.readouterr().out
    assert "gyro-bias: the filter's own state, not fitted" in text
    assert "by the filter's likelihood" in text
    assert out.is_file() and (tmp_path / "ident" / "rig-residuals.png").stat().st_size > 10_000
    overlay = (tmp_path / "ident" / "rig-config.toml").read_text()
    assert "mounting_rpy_rad" in overlay


def _turning_recording(yaw_rad_s: float, duration_s: float) -> filter_fit.FilterRecording:
    """A recording whose IMU reports the sensor pitched 80 degrees and turning about the
    world's vertical at ``yaw_rad_s`` from 0.5 s on."""
    t = np.arange(0.0, duration_s, 0.01) + 100.0
    imu = np.zeros(len(t), dtype=[(c, float) for c in ("t_s", "roll_rad", "pitch_rad", "yaw_rad")])
    imu["t_s"], imu["pitch_rad"] = t, np.radians(80.0)
    imu["yaw_rad"] = yaw_rad_s * np.clip(t - 100.5, 0.0, None)
    return filter_fit.FilterRecording("log", {"imu": imu})


def test_a_window_past_the_roll_over_is_warned_with_the_until_that_ends_it_before():
    """The windows of real-time recordings that fitted turned up to 25 degrees, the one that
    broke 90."""
    turning = _turning_recording(np.radians(10.0), 8.0)  # 30 degrees at 3.5 s, 45 at 5 s
    assert filter_fit.turned_s(turning, np.radians(30.0)) == pytest.approx(3.5, abs=0.011)
    warning = filter_fit.roll_over_warning(turning)
    assert "turns 45 degrees from its start 5.0" in warning and "--until 3.5 " in warning
    assert filter_fit.roll_over_warning(_turning_recording(np.radians(10.0), 5.0)) is None
