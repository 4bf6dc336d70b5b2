"""The IMU's latency, late IMU and servo samples (the run loop's timing), and the mean-force
kink."""

from dataclasses import replace

import numpy as np

from gyrohost.estimator import EstimatorConfig
from gyrohost.estimator.ekf import TensegrityEKF
from gyrohost.estimator.imu_prediction import predict_imu
from gyrohost.estimator.kink import expected_positive_part, kink_weight
from gyrohost.estimator.layout import from_model_state, layout_of
from gyrohost.estimator.process_model import ProcessModel
from gyrohost.geometry import euler_zyx


def _exact_sample(ekf):
    """The noise-free IMU sample of the filter's own state: rate, specific force, angles."""
    pred = predict_imu(ekf, ekf.x, ekf.u)
    return pred.omega + ekf.x[ekf.layout.bias], pred.specific_force, euler_zyx(pred.R_ws)


def test_a_sample_is_fused_its_latency_before_its_stamp(model, moving_state):
    x, _, _ = moving_state
    cfg = replace(EstimatorConfig(), imu_latency_s=2e-3)
    ekf = TensegrityEKF(model, cfg, x0=x, t0_s=0.8)
    ekf.fuse_imu(0.81, *_exact_sample(ekf))
    assert abs(ekf.t - 0.808) < 1e-12


def test_a_sample_the_filter_has_passed_is_compared_at_its_own_time(model, moving_state):
    x, _, _ = moving_state
    ekf = TensegrityEKF(model, EstimatorConfig(), x0=x, t0_s=0.8)
    sample = _exact_sample(ekf)  # taken at 0.8 s, reaching the filter after it passed 0.804 s
    ekf.advance(0.804)
    now = _exact_sample(ekf)
    innovations = {}
    ekf.log = lambda r: innovations.setdefault(r.source, r.innovation)
    ekf.fuse_imu(0.8, *sample)
    assert abs(ekf.imu_lag_s - 0.004) < 1e-12
    for source, k in (("imu_rate", 0), ("imu_angle", 2)):
        as_now = np.linalg.norm(sample[k] - now[k])  # the sample against the state at 0.804 s
        taken_back = np.linalg.norm(innovations[source])
        assert taken_back < 0.1 * as_now, (source, taken_back, as_now)


def test_a_servo_read_the_filter_has_passed_is_compared_at_its_own_time(model, moving_state):
    x, _, _ = moving_state
    ekf = TensegrityEKF(model, EstimatorConfig(), x0=x, t0_s=0.8)
    L = ekf.layout
    rest = ekf.u[: L.n_strings].copy()
    rest[0] += 0.01  # the servo 1 cm behind its command: its length moves at 0.2 m/s
    ekf.set_input(rest, 0.8)
    strings = np.arange(L.n_strings)
    sample = ekf.x[L.rest].copy()  # read at 0.8 s, reaching the filter after it passed 0.808 s
    ekf.advance(0.808)
    as_now = np.linalg.norm(sample - ekf.x[L.rest])
    innovations = {}
    ekf.log = lambda r: innovations.setdefault(r.source, r.innovation)
    ekf.fuse_servos(0.8, sample, strings)
    taken_back = np.linalg.norm(innovations["servos"])
    assert as_now > 1e-3  # 8 ms at 0.2 m/s: far outside the servos' noise
    assert taken_back < 1e-3 * as_now, (taken_back, as_now)


def test_expected_positive_part_and_its_variance_by_sampling():
    z = np.random.default_rng(1).standard_normal(400_000)
    for a in (-2.0, -0.5, 0.0, 0.7, 3.0):
        sampled = np.maximum(a - z, 0.0)
        assert abs(expected_positive_part(a) - sampled.mean()) < 5e-3, a
        variance = kink_weight(a) - (expected_positive_part(a) - max(a, 0.0)) ** 2
        assert abs(variance - sampled.var()) < 1e-2, a
    h = 1e-20  # complex-step safe: the derivative is Phi(a)
    assert abs(expected_positive_part(0.3 + 1j * h).imag / h - 0.6179114221889523) < 1e-12


def test_mean_kink_pulls_with_the_expected_force_of_the_jittered_strings(model):
    q = 2e-10
    cfg = replace(EstimatorConfig(), rest_jitter_psd_m2_s=q, kink_model="mean")
    mean_pm = ProcessModel(model, cfg)
    sharp_pm = ProcessModel(model, replace(cfg, kink_model="sharp"))
    L = layout_of(model)
    u = model.input_at(0.0)
    x = from_model_state(model, model.initial_state(), u)[: L.n_dynamic]
    x[L.rest] += (-1e-4, 5e-5)  # one string just taut, one just slack (jitter std 0.14 mm)
    X = np.tile(x, (100_000, 1))
    X[:, L.rest] += np.sqrt(q / cfg.process_dt_s) * np.random.default_rng(2).standard_normal(
        (len(X), L.n_strings)
    )
    sampled = sharp_pm.derivative(X, u)[:, L.q_dot]
    mean = mean_pm.derivative(x[None, :], u)[0, L.q_dot]
    sharp = sharp_pm.derivative(x[None, :], u)[0, L.q_dot]
    error = np.abs(mean - sampled.mean(axis=0)).max()
    assert error < 4.0 * sampled.std(axis=0).max() / np.sqrt(len(X))
    assert np.abs(sharp - sampled.mean(axis=0)).max() > 10.0 * error  # the kink rectifies
    # the rest-length states keep their own lag to the command
    assert np.array_equal(
        mean_pm.derivative(x[None, :], u)[0, L.rest], sharp_pm.derivative(x[None, :], u)[0, L.rest]
    )
