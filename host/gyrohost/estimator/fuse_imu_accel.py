"""IMU specific force: ``z = R_ws^T (a_imu - g)`` (m/s^2, sensor axes).

The acceleration of the IMU point comes from the dynamics (it depends on the input ``u``), so the
Jacobian is one batched complex-step call of the dynamics over all dynamic states.
"""

import numpy as np

from . import complex_step
from .fusion import Innovation, fuse

SOURCE = "imu_accel"
LABELS = ("x", "y", "z")
UNIT = "m_s2"


def predict(ekf, x, u):
    """Predicted specific force (3,) m/s^2 and its Jacobian (3, n)."""
    L = ekf.layout
    cols = ekf.dynamic_columns
    X = complex_step.perturbed(x, cols)
    K, m = X.shape[0], L.m
    q, q_dot = X[:, L.q].reshape(K, 3, m), X[:, L.q_dot].reshape(K, 3, m)
    _, N_ddot = ekf.process.dyn.accelerations(q, q_dot, X[:, L.omega], u)
    N, N_dot = ekf.batch_nodes(X)
    R_ws, _ = ekf.imu.frame(N, N_dot)
    value, J = complex_step.split(ekf.imu.specific_force(R_ws, N_ddot))
    H = np.zeros((3, L.size))
    H[:, cols] = J
    return value, H


def fuse_accel(ekf, accel_m_s2) -> Innovation:
    """Fuse one specific-force sample (3,) m/s^2 taken at the filter's current time."""
    hx, H = predict(ekf, ekf.x, ekf.u)
    R = np.eye(3) * ekf.config.imu_accel_std_m_s2**2
    return fuse(ekf, SOURCE, np.asarray(accel_m_s2, float), hx, H, R)
