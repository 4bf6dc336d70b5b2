"""The identified constants' errors considered (:mod:`gyrohost.estimator.consider`): the update
is the Joseph form with their gain rows zeroed, their entries and covariance block stay the
prior's through a run's samples, and estimated they move."""

from dataclasses import replace

import numpy as np
import pytest

from gyrohost.estimator import TensegrityEKF, sample_feed
from gyrohost.estimator.config import config_from_dict
from gyrohost.estimator.consider import considered_columns
from gyrohost.estimator.errors import EstimatorConfigError

KEYS = {
    "imu_mounting_std_rad": (2e-3, 1e-3, 3e-3),
    "string_cov_rel2": ((4e-3, 1e-3), (1e-3, 2e-2)),
    "j3_var_rel2": 9e-6,
    "imu_latency_std_s": 1e-3,
    "servo_delay_std_s": 3e-4,
}


def test_the_optimal_update_with_the_block_put_back_is_the_joseph_form_without_its_gain():
    # the identity consider.restore rests on, on a random prior and measurement
    rng = np.random.default_rng(3)
    n, k, c = 9, 4, np.array([2, 5, 6])
    A = rng.normal(size=(n, n))
    P = A @ A.T
    H = rng.normal(size=(k, n))
    B = rng.normal(size=(k, k))
    R = B @ B.T + np.eye(k)
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    optimal = P - K @ S @ K.T
    optimal[np.ix_(c, c)] = P[np.ix_(c, c)]
    K_c = K.copy()
    K_c[c] = 0.0
    I_KH = np.eye(n) - K_c @ H
    joseph = I_KH @ P @ I_KH.T + K_c @ R @ K_c.T
    assert np.allclose(optimal, joseph, rtol=0.0, atol=1e-12 * np.abs(P).max())
    assert np.linalg.eigvalsh(joseph).min() > 0.0


def _run(model, config, synthetic, mode):
    _, data = synthetic
    ekf = TensegrityEKF(model, replace(config, **KEYS, parameter_errors=mode))
    prior = ekf.x.copy(), ekf.P.copy()
    sample_feed.run(ekf, {name: rows[:60] for name, rows in data.items()})
    return ekf, prior


def test_considered_errors_keep_their_prior_through_the_samples(model, config, synthetic):
    ekf, (x0, P0) = _run(model, config, synthetic, "considered")
    L, c = ekf.layout, ekf.considered
    assert list(c) == [*range(L.mounting.start, L.mounting.stop), *range(L.params.start, L.size)]
    assert len(c) == 3 + 2 + 1 + 1 + 1
    assert np.all(ekf.x[c] == x0[c]) and np.all(ekf.P[np.ix_(c, c)] == P0[np.ix_(c, c)])
    assert np.abs(ekf.P[c, : L.n_dynamic]).max() > 0.0  # what they do to the motion is carried
    assert np.linalg.eigvalsh(0.5 * (ekf.P + ekf.P.T)).min() > -1e-12 * np.abs(ekf.P).max()
    assert np.all(ekf.x[L.bias] != x0[L.bias])  # the gyro's bias is the run's to learn


def test_estimated_errors_move(model, config, synthetic):
    ekf, (x0, P0) = _run(model, config, synthetic, "estimated")
    c = considered_columns(ekf.layout, "considered")
    assert ekf.considered.size == 0
    assert np.any(ekf.x[c] != x0[c])
    assert np.any(np.diag(ekf.P)[c] < np.diag(P0)[c])


def test_the_mode_is_one_of_two():
    with pytest.raises(EstimatorConfigError, match="parameter_errors"):
        config_from_dict({"parameter_errors": "learned"}, "rig.toml")
