"""IMU angular rate: ``z = omega_s(eta2, eta2_dot) + b_g`` (rad/s, sensor axes)."""

import numpy as np

from . import complex_step
from .fusion import Innovation, fuse

SOURCE = "imu_rate"
LABELS = ("x", "y", "z")
UNIT = "rad_s"


def predict(ekf, x):
    """Predicted rate (3,) rad/s and its Jacobian (3, n)."""
    L = ekf.layout
    cols = ekf.motion_columns
    N, N_dot = ekf.batch_nodes(complex_step.perturbed(x, cols))
    _, omega = ekf.imu.frame(N, N_dot)
    value, J = complex_step.split(omega)
    H = np.zeros((3, L.size))
    H[:, cols] = J
    H[:, L.bias] = np.eye(3)
    return value + x[L.bias], H


def fuse_rate(ekf, omega_rad_s) -> Innovation:
    """Fuse one angular-rate sample (3,) rad/s taken at the filter's current time."""
    hx, H = predict(ekf, ekf.x)
    R = np.eye(3) * ekf.config.imu_rate_std_rad_s**2
    return fuse(ekf, SOURCE, np.asarray(omega_rad_s, float), hx, H, R)
