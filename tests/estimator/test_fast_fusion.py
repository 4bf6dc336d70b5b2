"""The fast fusion (fusion._fuse_fast: stacked products, batched Cholesky, one solve for the
gain) against the reference (a Cholesky per measurement, filterpy's update), to round-off.

Tolerances: the same arithmetic in another order (a solve where filterpy inverts ``S``, an LU
solve of the triangular factor where scipy substitutes); the innovation covariance's condition
number here is below 1e6, so the gain and the whitened innovations agree to some 1e-10 of
their size at worst, and the covariance, a difference of terms of its own size, as well;
1e-8 fails on any wrong term (a missing ``K R K^T`` changes ``P`` at 1e-2)."""

import numpy as np
import pytest

from gyrohost.estimator import TensegrityEKF
from gyrohost.estimator.imu_model import euler_zyx

RTOL = 1e-8


def close(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return np.max(np.abs(a - b), initial=0.0) <= RTOL * max(np.max(np.abs(b), initial=0.0), 1e-300)


def assert_same_results(fast, ref):
    assert len(fast) == len(ref)
    for f, r in zip(fast, ref, strict=True):
        assert (f.source, f.accepted, f.rejected_count) == (r.source, r.accepted, r.rejected_count)
        assert close(f.innovation, r.innovation) and close(f.variance, r.variance)
        assert close(f.whitened, r.whitened)
        assert abs(f.nis - r.nis) <= RTOL * r.nis and abs(f.spread - r.spread) <= 1e-8


def assert_same_filters(fast, ref):
    assert close(fast.x, ref.x)
    assert close(fast.P, ref.P)


@pytest.fixture
def filters(model, config, moving_state):
    x, _, _ = moving_state
    return (
        TensegrityEKF(model, config, x0=x, fast=True),
        TensegrityEKF(model, config, x0=x, fast=False),
    )


def imu_sample(ekf, tilt_rad=0.0):
    """An IMU sample near the estimate (angles tilted by ``tilt_rad`` in pitch)."""
    R, _ = ekf.attitude()
    angles = euler_zyx(R[None])[0] + np.array([0.0, tilt_rad, 0.0])
    return np.array([0.01, -0.02, 0.03]), np.array([0.1, 0.0, 9.7]), angles


@pytest.mark.parametrize("tilt_rad", [0.0, 0.002, np.radians(20.0)])
def test_imu_fusion_equals_reference(filters, tilt_rad):
    """Accepted, slightly off and an outlier the gate rejects (the others then fused)."""
    fast, ref = filters
    sample = imu_sample(ref, tilt_rad)
    for t in (0.01, 0.02):
        results = [ekf.fuse_imu(t, *sample) for ekf in (fast, ref)]
        assert_same_results(*results)
        assert_same_filters(fast, ref)
    assert results[1][2].accepted == (tilt_rad < 0.1)


def test_wheel_and_servo_fusion_equal_reference(filters, model):
    fast, ref = filters
    omega = ref.x[ref.layout.omega] + 0.3
    lengths = ref.x[ref.layout.rest] + 1e-4
    for t in (0.01, 0.02):
        assert_same_results(*[ekf.fuse_wheels(t, omega) for ekf in (fast, ref)])
        assert_same_filters(fast, ref)
        assert_same_results(
            *[ekf.fuse_servos(t, lengths, list(range(model.alpha))) for ekf in (fast, ref)]
        )
        assert_same_filters(fast, ref)
