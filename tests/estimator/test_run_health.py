"""The estimator as the run loop feeds it: IMU samples fused at the IMU's reconstructed grid, the
health table of the run summary (NIS per source, gate rejections, NEES against the simulated
rig's truth) and the divergence that fails a run."""

from dataclasses import replace

import numpy as np
import pytest
from fake_loop import Ekf, Stream

from gyrohost.estimator.ekf import TensegrityEKF
from gyrohost.estimator.fusion import Innovation
from gyrohost.estimator.sample_feed import RegularClock, regular_times
from gyrohost.run.dispatch import ImuHandler
from gyrohost.run.health import (
    DIVERGED_NODE_ERROR_M,
    DIVERGED_REJECTED_IN_A_ROW,
    NisTally,
    TruthScore,
    fails_run,
    health,
    health_lines,
    rejection_warnings,
)


class _Sample:
    omega_rad_s = accel_m_s2 = euler_rad = (0.0, 0.0, 0.0)
    temperature_degC = 25.0


def test_the_run_loop_logs_arrivals_and_fuses_at_the_grid_replay_reconstructs(config):
    rng = np.random.default_rng(1)
    arrival = 0.01 * np.arange(60) + 5e-4 + rng.exponential(4e-3, 60)
    arrival[20:23] = arrival[22]  # a burst: three samples read at once
    stream, ekf = Stream(), Ekf()
    handler = ImuHandler(stream, config)
    for t in arrival:
        handler.take(float(t), _Sample(), ekf)
    assert [r[0] for r in stream.rows] == list(arrival)  # the log keeps the arrival stamps
    expected = regular_times(arrival, config.imu_period_s, config.imu_max_delay_s)
    assert np.array_equal(ekf.fused_at, expected)  # what gyrotens replay fuses them at
    assert np.all(np.diff(ekf.fused_at) > 0.0)  # the burst spread out
    late = np.asarray(ekf.fused_at[10:]) - 0.01 * np.arange(10, 60)
    assert np.ptp(late) < np.ptp(arrival[10:] - 0.01 * np.arange(10, 60))  # less jitter
    clock = RegularClock(0.0, 0.03)
    assert [clock(t) for t in (0.5, 0.5, 0.7)] == [0.5, 0.5, 0.7]  # period 0: the stamps


def _innovation(source, accepted, nis=3.0, k=3):
    return Innovation(source, 0.0, np.zeros(k), np.ones(k), nis, nis / 20.0, accepted, 0)


def test_nis_per_source_and_rejections_in_a_row_decide_divergence():
    tally = NisTally()
    for _ in range(10):
        tally.add(_innovation("imu_rate", True, nis=2.0))
        tally.add(_innovation("wheels", True, nis=6.0, k=4))
    table = health(tally, None)
    assert not table["diverged"]
    rate = table["nis"]["imu_rate"]
    assert rate["mean"] == 2.0 and rate["dof"] == 3 and rate["samples"] == 10
    lo, hi = rate["bounds95"]
    assert lo < 3.0 < hi
    assert "nees" not in table  # no truth on a real rig
    for _ in range(DIVERGED_REJECTED_IN_A_ROW - 1):
        tally.add(_innovation("imu_rate", False, nis=500.0))
    assert not health(tally, None)["diverged"]
    tally.add(_innovation("imu_rate", False, nis=500.0))
    table = health(tally, None)
    assert table["diverged"] and "imu_rate" in table["why"]
    assert table["nis"]["imu_rate"]["rejected"] == DIVERGED_REJECTED_IN_A_ROW
    assert any("DIVERGED" in line for line in health_lines(table))
    assert fails_run(table)
    # an identification run's estimate runs on the scene still to be identified
    expected = {**table, "required": False}
    assert not fails_run(expected)
    (line,) = [line for line in health_lines(expected) if "diverged" in line]
    assert "imu_rate" in line and "expected on an identification run" in line
    tally.add(_innovation("imu_rate", True))
    assert not health(tally, None)["diverged"]  # fusing again


def _truth_of(ekf):
    N, _ = ekf.batch_nodes(ekf.x[None, :])
    names = list(ekf.model.structure.node_names)
    scene = [N[0][:, names.index(n)] for n in ekf.model.scene.node_names]
    L = ekf.layout
    return np.array(scene).T, ekf.x[L.omega].copy(), ekf.x[L.rest].copy()


def test_nees_against_the_truth_and_a_diverged_estimate(model, config):
    ekf = TensegrityEKF(model, config)
    score = TruthScore(ekf)
    N, omega, rest = _truth_of(ekf)
    score.truth(ekf.t - 0.003, N, omega, rest)
    score.estimate()
    score.estimate()  # the filter has not moved on: kept once
    score.truth(ekf.t + 0.007, N, omega, rest)  # the truth at the estimate's time is the estimate
    table = health(NisTally(), score)
    assert table["nees"]["samples"] == 1 and table["nees"]["mean"] < 1e-12
    assert table["nees"]["dof"] == 11  # 5 node coordinates (8 on the manifold less 3 of
    # translation), 4 wheels, 2 rests
    assert not table["diverged"]
    off = N + np.array([[0.1], [0.0], [0.0]])  # the whole structure 10 cm off along x
    for k in range(1, 11):
        ekf.t = 0.01 * k  # an estimate each 10 ms, scored as the truth comes after it
        score.estimate()
        score.truth(ekf.t + 0.005, off, omega, rest)
    table = health(NisTally(), score)
    assert table["nees"]["node_error_recent_rms_m"] > DIVERGED_NODE_ERROR_M
    assert table["diverged"] and "node error" in table["why"]


def test_an_estimate_is_scored_against_the_truth_at_its_own_time(model, config):
    """Between two truth samples the truth is interpolated to the estimate's time: a node
    moving at constant speed is where the estimate says when the estimate is there, though
    neither truth sample is (the nearest sample would put it 5 mm off)."""
    ekf = TensegrityEKF(model, config)
    N, omega, rest = _truth_of(ekf)
    step = np.zeros_like(N)
    step[0, 0] = 1e-2  # node n1 moves 10 mm along x between the truth samples
    score = TruthScore(ekf)
    score.estimate()  # before every truth sample: never scored
    ekf.t += 0.01
    score.truth(ekf.t - 0.005, N - step / 2, omega, rest)
    score.estimate()
    score.truth(ekf.t + 0.005, N + step / 2, omega, rest)
    assert len(score.nees) == 1 and score.nees[0] < 1e-9
    nearest = TruthScore(ekf)
    nearest.truth(ekf.t - 0.001, N - step / 2, omega, rest)
    nearest.truth(ekf.t, N - step / 2, omega, rest)
    nearest.estimate()
    assert nearest.nees[0] > 1.0  # what scoring at the nearest sample's time would have said


def test_the_nees_is_scored_sample_by_sample_not_as_independent_samples(model, config):
    """One run's NEES samples are correlated from step to step, so the summary gives the share
    of samples inside their own 95 % bounds, not bounds of a mean over them."""
    score = TruthScore(TensegrityEKF(model, config))
    score.dof = 14  # per sample: [5.63, 26.12]
    score.nees = [1.0, 10.0, 14.0, 30.0]
    score.node_error_m = [1e-3] * 4
    table = health(NisTally(), score)
    assert table["nees"]["inside"] == 0.5
    assert table["nees"]["sample_bounds95"] == pytest.approx([5.629, 26.119], abs=1e-3)
    assert "bounds95" not in table["nees"]
    (line,) = [line for line in health_lines(table) if "NEES" in line]
    assert "50.0 % of 4 samples inside their 95 % bounds [5.63, 26.12]" in line


def test_a_source_refused_at_a_stretch_longer_than_stated_is_warned_about():
    """An IMU stall's late burst refused by the gate: 0.3 s of rejections (30 samples, fewer
    than the 50 in a row that make a divergence) is named with its time; 0.2 s is not."""

    def at(source, t_s, accepted):
        return replace(_innovation(source, accepted), t_s=t_s)

    tally = NisTally()
    for k in range(100):  # 10 ms apart: rejected from 0.30 s to 0.60 s, then fused again
        tally.add(at("imu_angle", 0.01 * k, not 30 <= k < 60))
        tally.add(at("imu_rate", 0.01 * k, not 30 <= k < 50))  # 0.20 s: within the limit
    table = health(tally, None)
    assert not table["diverged"]
    angle = table["nis"]["imu_angle"]
    assert angle["longest_rejected_s"] == pytest.approx(0.30) and angle["rejected"] == 30
    assert angle["longest_rejected_from_s"] == pytest.approx(0.30)
    (line,) = rejection_warnings(table)
    assert line.startswith("estimator: the gate refused every imu_angle sample for 0.30 s from "
                           "t = 0.30 s (more than 0.25 s)")  # fmt: skip
