"""The wheel telemetry's noise as an MA(1) state (``wheel_noise_ma1``): the fusion against the
update of the state augmented with the sample's own noise term, computed here directly."""

import numpy as np
import pytest

from gyrohost.estimator import TensegrityEKF, config_from_dict
from gyrohost.estimator.fuse_wheels import white_std

THETA = -0.6


def _ekf(model, **keys):
    ekf = TensegrityEKF(model, config_from_dict({"wheel_noise_ma1": THETA, **keys}))
    ekf.advance(0.05)  # correlations between the blocks
    return ekf


def test_white_noise_adds_no_states(model, config):
    ekf = TensegrityEKF(model, config)
    assert ekf.layout.size == 33 and ekf.layout.n_wheel_noise == 0
    assert not any(name.startswith("wheel_noise") for name in ekf.layout.labels())


def test_noise_states_start_at_zero_with_their_white_variance(model):
    ekf = _ekf(model)
    L = ekf.layout
    assert L.size == 37 and L.labels()[-1] == "wheel_noise3_rad_s"
    assert np.all(ekf.x[L.wheel_noise] == 0.0)
    var_a = ekf.config.wheel_speed_std_rad_s**2 / (1.0 + THETA**2)
    assert np.allclose(np.diag(ekf.P)[L.wheel_noise], var_a)
    assert abs(white_std(ekf.config) ** 2 - var_a) < 1e-15


def _augmented_update(ekf, z):
    """The exact update: state and the sample's noise term a_k (prior 0, var(a), independent),
    ``z = omega + theta a_{k-1} + a_k`` without further noise; a_k then takes a_{k-1}'s place."""
    L, n, k = ekf.layout, ekf.layout.size, ekf.layout.n_wheels
    var_a = white_std(ekf.config) ** 2
    x = np.concatenate([ekf.x, np.zeros(k)])
    P = np.zeros((n + k, n + k))
    P[:n, :n] = ekf.P
    P[n:, n:] = var_a * np.eye(k)
    H = np.zeros((k, n + k))
    H[:, L.omega] = np.eye(k)
    H[:, L.wheel_noise] = THETA * np.eye(k)
    H[:, n:] = np.eye(k)
    S = H @ P @ H.T
    K = P @ H.T @ np.linalg.inv(S)
    x = x + K @ (z - H @ x)
    P = P - K @ S @ K.T
    keep = np.r_[0 : L.wheel_noise.start, n : n + k]  # a_k in a_{k-1}'s place
    x, P = x[keep], P[np.ix_(keep, keep)]
    return ekf.manifold.condition(x, P)


def test_fusion_is_the_augmented_update(model):
    ekf = _ekf(model)
    ekf.fuse_wheels(ekf.t, ekf.x[ekf.layout.omega] + 0.01)  # a first sample: a state nonzero
    ekf.advance(ekf.t + 0.01)
    z = ekf.x[ekf.layout.omega] + np.array([0.02, -0.01, 0.005, 0.0])
    x_ref, P_ref = _augmented_update(ekf, z)
    (result,) = ekf.fuse_wheels(ekf.t, z)
    assert result.accepted
    assert np.abs(ekf.x[ekf.layout.wheel_noise]).max() > 1e-4  # the sample's a estimated
    assert np.allclose(ekf.x, x_ref, rtol=0, atol=1e-12)
    assert np.allclose(ekf.P, P_ref, rtol=0, atol=1e-12 * np.abs(P_ref).max())


def test_a_rejected_sample_leaves_its_noise_term_unknown(model):
    ekf = _ekf(model)
    L = ekf.layout
    ekf.fuse_wheels(ekf.t, ekf.x[L.omega] + 0.01)
    x_before = ekf.x.copy()
    (result,) = ekf.fuse_wheels(ekf.t, ekf.x[L.omega] + 100.0)
    assert not result.accepted
    base = slice(0, L.wheel_noise.start)
    assert np.allclose(ekf.x[base], x_before[base], rtol=0, atol=1e-12)
    assert np.all(ekf.x[L.wheel_noise] == 0.0)
    P = ekf.P
    assert np.allclose(P[L.wheel_noise, L.wheel_noise], white_std(ekf.config) ** 2 * np.eye(4))
    assert not P[L.wheel_noise, : L.wheel_noise.start].any()


@pytest.mark.parametrize("theta", [-1.0, 1.0])
def test_the_coefficient_stays_invertible(model, theta):
    from gyrohost.estimator import EstimatorConfigError

    with pytest.raises(EstimatorConfigError, match="wheel_noise_ma1"):
        config_from_dict({"wheel_noise_ma1": theta})
