"""The compiled IMU prediction (estimator.fast_imu) against the reference
(imu_prediction.predict_imu, closed form), to round-off.

Tolerances: the frame's derivatives in forward mode over its twelve inputs chained to the
states, against the complex step over the states; both exact up to round-off of the frame's
few dozen operations, some 1e-15 of each field's largest entry; the accelerations' Jacobian is
the same kernel call in both. 1e-10 leaves room for other CPUs and fails on any wrong term (a
missing chain-rule term changes a column at its own size)."""

from dataclasses import replace

import numpy as np
import pytest

from gyrohost.estimator import TensegrityEKF, fuse_imu_accel, fuse_imu_angle, fuse_imu_rate
from gyrohost.estimator.fast_imu import fast_imu
from gyrohost.estimator.imu_prediction import predict_imu

RTOL = 1e-10


def assert_same_prediction(got, want):
    for name, value in vars(want).items():
        other = getattr(got, name)
        assert other.shape == value.shape, name
        scale = max(np.max(np.abs(value)), 1e-300)
        assert np.max(np.abs(other - value)) <= RTOL * scale, name


@pytest.mark.parametrize(
    "keys",
    [
        {},
        {"imu_mounting_rpy_rad": (0.02, -0.05, 0.3)},
        {"imu_mounting_std_rad": (0.01, 0.01, 0.02)},  # the mounting as a state
        {"wheel_lag_s": 0.013},
        {"kink_model": "mean", "rest_jitter_psd_m2_s": 2e-10},
    ],
)
def test_imu_prediction_equals_reference(model, config, moving_state, keys):
    x, _, u = moving_state
    ekf = TensegrityEKF(model, replace(config, **keys), x0=x)
    if keys.get("wheel_lag_s"):
        ekf.set_input(u[: model.alpha], wheel_speed_rad_s=ekf.x[ekf.layout.omega] + 2.0)
    x = ekf.x.copy()
    if ekf.layout.n_mounting:
        x[ekf.layout.mounting] = [0.004, -0.003, 0.01]
    assert_same_prediction(fast_imu(ekf)(x, ekf.u), predict_imu(ekf, x, ekf.u))


def test_uncovered_configurations_have_no_fast_imu(model, config):
    assert fast_imu(TensegrityEKF(model, replace(config, process_method="rk4"))) is None
    assert fast_imu(TensegrityEKF(model, config, fast=False)) is None


@pytest.mark.parametrize(
    "keys",
    [
        {},
        {"imu_time_std_s": 0.002, "imu_mounting_std_rad": (0.01, 0.01, 0.02)},
        {"init_accel_bias_std_m_s2": 0.05, "imu_mounting_rpy_rad": (0.02, -0.05, 0.3)},
    ],
)
def test_imu_measurements_equal_reference(model, config, moving_state, keys):
    """The rate, specific force and attitude measurements, the sample taken 3 ms back."""
    x, _, u = moving_state
    ekf = TensegrityEKF(model, replace(config, **keys), x0=x)
    ekf.imu_lag_s = 0.003
    pred = predict_imu(ekf, ekf.x, ekf.u)
    sample = (np.array([0.1, -0.2, 0.05]), np.array([0.3, 0.1, 9.6]), np.array([0.2, -1.4, 2.9]))
    got = fast_imu(ekf).measurements(pred, *sample)
    modules = (fuse_imu_rate, fuse_imu_accel, fuse_imu_angle)
    want = [m.measurement(ekf, pred, z) for m, z in zip(modules, sample, strict=True)]
    for g, w in zip(got, want, strict=True):
        assert g.source == w.source
        for name in ("z", "hx", "H", "R"):
            a, b = getattr(g, name), getattr(w, name)
            assert np.max(np.abs(a - b)) <= RTOL * max(np.max(np.abs(b)), 1e-300), (g.source, name)
