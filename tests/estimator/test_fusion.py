"""Gating, time-outs, status bits and the manifold after updates."""

import numpy as np
import pytest
from filter_states import to_model_state

from gyrohost.estimator import (
    EstimatorConfigError,
    EstimatorError,
    Status,
    TensegrityEKF,
    config_from_dict,
)
from gyrohost.estimator.fusion import Measurement, fuse
from gyrohost.estimator.imu_model import euler_zyx
from gyrotensegrity.projection import project


def imu_sample(ekf):
    """A noise-free IMU sample consistent with the present estimate (at rest, level)."""
    R, _ = ekf.attitude()
    return np.zeros(3), np.array([0.0, 0.0, 9.80665]), euler_zyx(R[None])[0]


def test_gate_rejects_an_outlier_and_counts_it(model, config):
    seen = []
    ekf = TensegrityEKF(model, config, log=seen.append)
    rate, accel, angle = imu_sample(ekf)
    ekf.fuse_imu(0.01, rate, accel, angle)
    assert not ekf.status & Status.IMU_ANGLE_REJECTED
    outlier = angle + np.radians([0.0, 20.0, 0.0])
    results = ekf.fuse_imu(0.02, rate, accel, outlier)
    by_source = {r.source: r for r in results}
    bad = by_source["imu_angle"]
    assert not bad.accepted and bad.test_ratio > 1.0 and bad.rejected_count == 1
    assert by_source["imu_rate"].accepted and by_source["imu_accel"].accepted
    assert ekf.monitors["imu_angle"].rejected == 1
    assert ekf.status & Status.IMU_ANGLE_REJECTED
    _, est = ekf.attitude()
    assert abs(est[1] - angle[1]) < np.radians(0.5)  # the outlier did not pull the estimate
    assert seen[-1] is bad  # logged, innovation, variance and ratio included
    assert bad.innovation.shape == (3,) and np.all(bad.variance > 0.0)
    ekf.fuse_imu(0.03, rate, accel, angle)
    assert not ekf.status & Status.IMU_ANGLE_REJECTED
    assert ekf.monitors["imu_angle"].rejected == 1


def test_time_out_predicts_only_raises_flags_and_recovers(model, config):
    ekf = TensegrityEKF(model, config)
    rate, accel, angle = imu_sample(ekf)
    omega_w = ekf.x[ekf.layout.omega].copy()
    for k in range(1, 11):
        ekf.fuse_imu(0.01 * k, rate, accel, angle)
        ekf.fuse_wheels(0.01 * k, omega_w)
        ekf.fuse_servos(0.01 * k, [0.43105229381822, 0.43105229381132], [0, 1])
    assert ekf.status == Status(0)
    accepted = {s: m.accepted for s, m in ekf.monitors.items()}
    P_before = np.trace(ekf.P)
    ekf.advance(0.35)  # IMU and wheels silent for 0.25 s, servos not yet timed out
    assert ekf.status & Status.IMU_RATE_TIMEOUT and ekf.status & Status.WHEELS_TIMEOUT
    assert not ekf.status & Status.SERVOS_TIMEOUT
    assert not ekf.status & Status.PREDICTION_ONLY
    ekf.advance(0.7)
    assert ekf.status & Status.PREDICTION_ONLY and ekf.status & Status.SERVOS_TIMEOUT
    assert {s: m.accepted for s, m in ekf.monitors.items()} == accepted  # nothing fused
    assert np.trace(ekf.P) > P_before  # uncertainty grows on prediction alone
    ekf.fuse_imu(0.71, rate, accel, angle)
    assert not ekf.status & (Status.PREDICTION_ONLY | Status.IMU_ANGLE_TIMEOUT)
    assert ekf.status & Status.WHEELS_TIMEOUT  # still silent
    ekf.fuse_wheels(0.72, omega_w)
    assert not ekf.status & Status.WHEELS_TIMEOUT
    assert ekf.monitors["imu_rate"].timeouts == 1


def test_stale_sample_is_dropped_and_flagged(model, config):
    ekf = TensegrityEKF(model, config)
    rate, accel, angle = imu_sample(ekf)
    ekf.fuse_imu(0.2, rate, accel, angle)
    assert ekf.fuse_wheels(0.1, ekf.x[ekf.layout.omega]) == []
    assert ekf.status & Status.STALE_SAMPLE and ekf.monitors["wheels"].stale == 1


def test_estimate_on_manifold_after_every_update(model, config, synthetic):
    truth, data = synthetic
    ekf = TensegrityEKF(model, config)
    m = ekf.manifold
    checks = []

    def check(e, stream):
        B, B_dot = m.bars(e.x)
        length_err = np.abs(np.linalg.norm(B, axis=0) - model.l)
        rate_err = np.abs(np.sum(B * B_dot, axis=0))
        cov_err = np.abs(m.jacobian(e.x) @ e.P).max() / np.abs(e.P).max()
        if stream == "predict" or e.monitors.get(stream, e.monitors["imu_rate"]).last_rejected:
            cov_err = 0.0  # P is projected by updates; a prediction adds noise everywhere
        checks.append((length_err.max(), rate_err.max(), cov_err))

    from gyrohost.estimator import sample_feed

    sample_feed.run(ekf, {k: v[:40] for k, v in data.items()}, check)
    worst = np.max(checks, axis=0)
    assert len(checks) > 80
    assert worst[0] < 1e-12 and worst[1] < 1e-12 and worst[2] < 1e-9
    # the estimator's dense projection is the model's projection
    xm = to_model_state(model, ekf.x + 1e-3)
    ref = project(model, xm)
    mine = to_model_state(model, m.project_state(ekf.x + 1e-3))
    assert np.max(np.abs(ref - mine)) < 1e-12


def test_non_finite_measurement_is_rejected_not_propagated(model, config):
    ekf = TensegrityEKF(model, config)
    rate, accel, angle = imu_sample(ekf)
    results = ekf.fuse_imu(0.01, rate + np.nan, accel, angle)
    assert not results[0].accepted and np.all(np.isfinite(ekf.x))


def test_non_finite_state_raises_with_member(model, config):
    ekf = TensegrityEKF(model, config)
    ekf.kf.x[3 * model.m, 0] = np.inf
    # either the model's fast path refuses the state (naming the bar) or the check after the
    # step names the state entry; both with the time
    with pytest.raises(EstimatorError, match=r"t = 0.01 s: prediction") as exc:
        ekf.advance(0.01)
    assert exc.value.member and exc.value.t_s == pytest.approx(0.01)


def test_config_errors_name_the_key():
    with pytest.raises(EstimatorConfigError, match="imu_rate_std_rad_s"):
        config_from_dict({"imu_rate_std_rad_s": -1.0})
    with pytest.raises(EstimatorConfigError, match="unknown estimator key 'gate'"):
        config_from_dict({"gate": 3})
    with pytest.raises(EstimatorConfigError, match="process_method"):
        config_from_dict({"process_method": "euler"})
    assert config_from_dict({"imu_frame_nodes": ["n1", "n3", "n4"]}).imu_frame_nodes[2] == "n4"


def test_whitened_innovation_is_the_innovation_over_its_covariance_factor(model, config):
    """``whitened`` is ``L^-1 y`` with ``S = L L^T`` (the prediction-error fit's residual):
    its squares sum to the NIS and ``L w`` gives the innovation back."""
    ekf = TensegrityEKF(model, config)
    rate, accel, angle = imu_sample(ekf)
    results = ekf.fuse_imu(0.01, rate + 0.01, accel - 0.05, angle + np.radians(0.3))
    for r in results:
        assert r.nis > 0.0 and np.isclose(r.whitened @ r.whitened, r.nis, rtol=1e-12)
    # against S built by hand from the filter before the update
    ekf2 = TensegrityEKF(model, config)
    H = np.zeros((2, len(ekf2.x)))
    H[0, 0], H[1, 0], H[1, 1] = 1.0, 1.0, 1.0
    R = np.diag([4e-6, 1e-6])
    S = H @ ekf2.P @ H.T + R
    z = np.array([1e-3, -2e-3])
    (r,) = fuse(ekf2, Measurement("imu_rate", z, np.zeros(2), H, R))
    assert np.allclose(np.linalg.cholesky(S) @ r.whitened, z, rtol=1e-10)
    assert np.isclose(r.nis, z @ np.linalg.solve(S, z), rtol=1e-10)
    # the likelihood's other term: how far the state's uncertainty widens S beyond R
    spread = np.linalg.slogdet(S)[1] - np.linalg.slogdet(R)[1]
    assert spread > 0.0 and np.isclose(r.spread, spread, rtol=1e-10)


def test_a_finite_state_the_imu_cannot_see_raises_with_member(model, config):
    """Nodes 1e200 m out (a diverged prediction) are finite, but the model refuses the state
    the IMU's prediction linearises at: the estimator's error, naming the member, not the
    model's."""
    ekf = TensegrityEKF(model, config)
    ekf.kf.x[: 3 * model.m, 0] *= 1e200
    rate, accel, angle = imu_sample(TensegrityEKF(model, config))
    with pytest.raises(EstimatorError, match=r"t = 0 s: the IMU's prediction failed") as exc:
        ekf.fuse_imu(ekf.t + config.imu_latency_s, rate, accel, angle)
    assert exc.value.member and exc.value.t_s == 0.0


@pytest.mark.parametrize("fast", [True, False])
def test_predicted_axes_that_are_not_a_rotation_raise_with_member(model, config, monkeypatch, fast):
    """Finite axes that are no rotation (a frame whose nodes overflowed) are refused by name
    before the angle's rotation would reject them with a bare ValueError."""
    from dataclasses import replace

    from gyrohost.estimator import ekf as ekf_module

    squashed = np.diag([1.0, 1.0, 0.01])

    def squashing(predict):
        return lambda *a: replace(predict(*a), R_ws=predict(*a).R_ws @ squashed)

    monkeypatch.setattr(ekf_module, "predict_imu", squashing(ekf_module.predict_imu))
    ekf = TensegrityEKF(model, config, fast=fast)
    assert (ekf.fast_imu is not None) == fast
    if fast:  # the stages' IMU prediction squashed, the one-call cycle off
        monkeypatch.setattr(ekf, "fast_imu", squashing(ekf.fast_imu))
        monkeypatch.setattr(ekf, "cycle", None)
    rate, accel, angle = imu_sample(ekf)
    with pytest.raises(EstimatorError, match=r"not a rotation \(R\^T R off the identity by 1\)"):
        ekf.fuse_imu(ekf.t + config.imu_latency_s, rate, accel, angle)


def test_an_update_whose_stacked_covariance_is_singular_raises_with_its_sources(model, config):
    """Two samples each with a positive definite ``S`` (each passes its gate) whose stacked
    ``S`` is singular (the same row twice, no sensor noise): the reference update's inverse
    fails, and the filter stops with an error naming them (the likelihood fit walls such a
    trial off), not a linear-algebra traceback."""
    ekf = TensegrityEKF(model, config, fast=False)
    H = np.zeros((1, len(ekf.x)))
    H[0, 0] = 1.0
    sources = ("imu_rate", "imu_accel")
    twice = [Measurement(s, np.array([1e-4]), np.zeros(1), H, np.zeros((1, 1))) for s in sources]
    with pytest.raises(EstimatorError, match="update of imu_rate, imu_accel is singular") as caught:
        fuse(ekf, *twice)
    assert caught.value.member == "imu_rate, imu_accel"
