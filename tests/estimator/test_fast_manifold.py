"""The compiled manifold projections (estimator.fast_manifold) against the reference
(estimator.manifold), to round-off.

Tolerances: the same Gauss-Newton steps and projector in another order (Cholesky for the Gram
matrices where the reference solves by LU, ``Pi P`` without forming ``Pi``). The bars' Gram
matrices are well conditioned on the D-bar (bars far from parallel), so the steps agree to a
few ulp of the coordinates and the covariance to some 1e-14 of its largest entry; 1e-10
leaves room for other BLAS kernels and fails on any wrong term (a wrong row of ``G`` leaves a
constraint direction in ``P`` at its own size)."""

import numpy as np
import pytest

from gyrohost.estimator import TensegrityEKF
from gyrohost.estimator.fast_manifold import FastManifold
from gyrohost.estimator.manifold import Manifold

RTOL = 1e-10


@pytest.fixture
def pair(model, config):
    ekf = TensegrityEKF(model, config, fast=False)
    return FastManifold(model, ekf.layout), Manifold(model, ekf.layout), ekf


def off_manifold(ekf, moving_state, size_m):
    """The moving state pushed off the constraints by ``size_m`` (positions) and ``10 size_m``
    per second (velocities), reproducibly."""
    x, _, _ = moving_state
    x = np.concatenate([x, np.zeros(ekf.layout.size - len(x))])
    push = np.random.default_rng(3).normal(size=x.size)
    L = ekf.layout
    x[L.q] += size_m * push[L.q]
    x[L.q_dot] += 10.0 * size_m * push[L.q_dot]
    return x


@pytest.mark.parametrize("size_m", [0.0, 1e-9, 1e-3])
def test_projection_equals_reference(pair, moving_state, size_m):
    fast, ref, ekf = pair
    x = off_manifold(ekf, moving_state, size_m)
    got, want = fast.project_state(x), ref.project_state(x)
    assert np.max(np.abs(got - want)) <= RTOL * np.max(np.abs(want))
    assert np.max(np.abs(fast.residual(got))) < 1e-12


def test_conditioning_equals_reference(pair, moving_state):
    fast, ref, ekf = pair
    x = off_manifold(ekf, moving_state, 1e-4)
    A = np.random.default_rng(4).normal(size=(x.size, x.size)) * 1e-3
    P = A @ A.T + ekf.P
    (x1, P1), (x2, P2) = fast.condition(x, P), ref.condition(x, P)
    assert np.max(np.abs(x1 - x2)) <= RTOL * np.max(np.abs(x2))
    assert np.max(np.abs(P1 - P2)) <= RTOL * np.max(np.abs(P2))
    assert np.array_equal(P1, P1.T)
    G = ref.jacobian(x1)
    assert np.max(np.abs(G @ P1)) <= 1e-12 * np.max(np.abs(G)) * np.max(np.abs(P1))
