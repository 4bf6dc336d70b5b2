"""The IMU measurement model against finite differences of the frame and against closed forms."""

import numpy as np

from gyrohost.estimator.imu_model import ImuGeometry, euler_zyx
from gyrohost.geometry import rotation_zyx
from gyrotensegrity import evaluate


def test_rate_is_the_frame_rotation_rate(model, config, moving_state):
    _, x_model, u = moving_state
    geo = ImuGeometry(model, config)
    N, N_dot = model.nodes(x_model)
    R, omega = geo.frame(N[None], N_dot[None])
    h = 1e-7
    R_ahead, _ = geo.frame((N + h * N_dot)[None], N_dot[None])
    R_back, _ = geo.frame((N - h * N_dot)[None], N_dot[None])
    W = R[0].T @ (R_ahead[0] - R_back[0]) / (2 * h)  # R^T R_dot
    assert np.max(np.abs(W + W.T)) < 1e-6  # skew-symmetric
    assert np.allclose(omega[0], [W[2, 1], W[0, 2], W[1, 0]], atol=1e-7)
    assert np.linalg.norm(omega[0]) > 0.01  # the structure does turn


def test_specific_force_and_angles_at_rest(model, config):
    geo = ImuGeometry(model, config)
    x = model.initial_state()
    ev = evaluate(0.0, x, model.input_at(0.0), model)
    R, omega = geo.frame(ev.N[None], ev.N_dot[None])
    f = geo.specific_force(R, ev.N_ddot[None])[0]
    assert np.allclose(R[0], np.eye(3)) and np.allclose(omega, 0.0)
    assert np.allclose(f, [0.0, 0.0, 9.80665], atol=1e-9)  # level and still: +g along z
    angles = np.array([0.1, -0.4, 2.5])
    assert np.allclose(euler_zyx(rotation_zyx(*angles)[None])[0], angles)
