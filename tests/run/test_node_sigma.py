"""The standard deviations the ``nodes`` stream logs, against the spread of node positions and
plane tilts of states drawn from the filter's covariance (an independent reference: no
Jacobian, no linearisation)."""

import numpy as np
import pytest

from gyrohost.control.attitude import attitude_of, node_columns
from gyrohost.estimator.config import EstimatorConfig
from gyrohost.estimator.ekf import TensegrityEKF
from gyrohost.resources import shipped
from gyrohost.run.uncertainty import NodeSigma
from gyrotensegrity import Model, load_scene

DRAWS = 20000


@pytest.mark.parametrize(
    ("scene", "imu_nodes"), [("dbar-gyro", ("n1", "n3", "n2")), ("prism-gyro", ("b1", "b2", "b3"))]
)
def test_logged_sigmas_match_the_spread_of_states_drawn_from_the_covariance(scene, imu_nodes):
    model = Model(load_scene(shipped("scene", scene)))
    ekf = TensegrityEKF(model, EstimatorConfig(imu_frame_nodes=imu_nodes))
    names = list(model.scene.node_names)
    cols = node_columns(model, names)
    tilt = attitude_of(model)
    sigma = NodeSigma(ekf, cols, tilt)
    rng = np.random.default_rng(3)
    # a covariance with correlations between the node coordinates, mm scale
    n = ekf.layout.size
    A = rng.normal(size=(n, n)) * 1e-3
    P = A @ A.T / n + np.diag(np.full(n, 1e-8))
    x = ekf.x.copy()
    N = ekf.batch_nodes(x[None])[0][0][:, cols]
    node_std, tilt_std = sigma.std(N, P)
    X = rng.multivariate_normal(x, P, DRAWS)
    drawn = ekf.batch_nodes(X)[0][:, :, cols]  # (DRAWS, 3, n)
    spread = drawn.transpose(0, 2, 1).reshape(DRAWS, -1).std(axis=0)
    # a sample standard deviation of 20000 draws is within 1.5 % of the true one (3 sigma)
    assert np.allclose(node_std, spread, rtol=0.015), np.max(np.abs(node_std / spread - 1))
    if tilt is None:
        assert tilt_std == ()
        return
    # about a millimetre of node error: the tilt is close to linear over the spread
    (value,) = tilt_std
    assert value == pytest.approx(float(np.std(tilt.tilt(drawn))), rel=0.02)


def test_batched_plane_tilt_is_the_documented_formula_per_sample():
    model = Model(load_scene(shipped("scene", "dbar-gyro")))
    meter = attitude_of(model)
    names = list(model.scene.node_names)
    rng = np.random.default_rng(4)
    N0 = model.structure.N0[:, node_columns(model, names)]
    batch = N0 + 0.1 * rng.normal(size=(30, *N0.shape))
    axis, n0 = meter.attitude.axis, meter.attitude.normal0
    expected = []
    for N in batch:  # control.attitude's docstring, with numpy's own cross products
        n1, n2, n3, n4 = (N[:, names.index(n)] for n in ("n1", "n2", "n3", "n4"))
        normal = np.cross(n3 - n1, n2 - n4)
        p = normal / np.linalg.norm(normal)
        p = p - (p @ axis) * axis
        expected.append(np.arctan2(np.cross(n0, p) @ axis, n0 @ p))
    assert np.allclose(meter.tilt(batch), expected, atol=1e-12)
    assert meter.tilt(batch[0]) == pytest.approx(expected[0], abs=1e-12)
