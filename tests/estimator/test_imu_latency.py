"""The IMU latency's error as a filter state (:mod:`gyrohost.estimator.imu_latency`): its
Jacobian columns against the measurements' rate along the model's own motion, its estimate
acting as the filter's lag behind the sample, its key and prior."""

from dataclasses import replace

import numpy as np
import pytest

from gyrohost.estimator import TensegrityEKF, fuse_imu_accel, fuse_imu_angle, fuse_imu_rate
from gyrohost.estimator.imu_latency import sample_lag_s, with_latency_columns
from gyrohost.estimator.imu_prediction import predict_imu

STD_S = 1e-3
SOURCES = (fuse_imu_rate, fuse_imu_accel, fuse_imu_angle)


def _filter(model, config, x):
    ekf = TensegrityEKF(model, replace(config, imu_latency_std_s=STD_S), x0=np.append(x, 0.0))
    return ekf


def _measurements(ekf, u):
    pred = predict_imu(ekf, ekf.x, u)
    made = [m.measurement(ekf, pred, np.zeros(3)) for m in SOURCES]
    return with_latency_columns(ekf, pred, made)


def test_the_latency_is_a_state_with_its_prior(model, config, moving_state):
    ekf = _filter(model, config, moving_state[0])
    L = ekf.layout
    assert L.labels()[L.imu_latency] == ["imu_latency_error_s"]
    assert ekf.P[L.imu_latency, L.imu_latency][0, 0] == STD_S**2
    assert TensegrityEKF(model, config).layout.size == L.size - 1


def test_the_latency_columns_are_minus_the_measurements_rate_along_the_motion(
    model, config, moving_state
):
    """A sample taken ``d`` earlier reads ``h(t - d)``: each column is ``-dh/dt``, here against
    a central difference of the predictions along the model's own motion (RK4 steps of
    +-10 us), to the difference's own error."""
    x, _, u = moving_state
    ekf = _filter(model, config, x)
    L = ekf.layout
    H = np.concatenate([m.H[:, L.imu_latency.start] for m in _measurements(ekf, u)])
    eps = 1e-5
    ahead = [ekf.process.step(ekf.x, u, s * eps)[0] for s in (1.0, -1.0)]

    def predicted(state):
        pred = predict_imu(ekf, state, u)
        return np.concatenate([pred.omega, pred.specific_force]), pred.R_ws

    (h1, R1), (h0, R0) = (predicted(s) for s in ahead)
    turn = R1 @ R0.T  # the sensor's turn over 2 eps, world axes, to first order
    w = 0.5 * (turn - turn.T)[[2, 0, 1], [1, 2, 0]] / (2 * eps)
    rate = np.concatenate([(h1 - h0) / (2 * eps), w])
    assert np.max(np.abs(H + rate)) <= 1e-6 * np.max(np.abs(rate))


def test_the_estimate_acts_as_a_lag_behind_the_sample(model, config, moving_state):
    """An estimated error ``d`` moves each prediction as the filter's lag ``d`` behind the
    sample does (:func:`.imu_prediction.at_sample_time`; the attitude's on the sample's side):
    it adds to the lag (:func:`sample_lag_s`), nothing else of the measurements moves."""
    x, _, u = moving_state
    ekf = _filter(model, config, x)
    ekf.x[ekf.layout.imu_latency] = 2e-3
    assert sample_lag_s(ekf, ekf.t - 1e-3) == pytest.approx(3e-3, rel=1e-12)
    ekf.imu_lag_s = sample_lag_s(ekf, ekf.t)  # a sample placed at the filter's time
    estimated = _measurements(ekf, u)
    ekf.x[ekf.layout.imu_latency] = 0.0
    ekf.imu_lag_s = 2e-3
    lagged = _measurements(ekf, u)
    for a, b in zip(estimated, lagged, strict=True):
        np.testing.assert_allclose(a.hx, b.hx, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(a.z, b.z, rtol=1e-12, atol=1e-15)
