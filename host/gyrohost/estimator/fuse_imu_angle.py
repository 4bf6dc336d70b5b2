"""IMU angles: ``z = euler_zyx(R_ws(eta2))`` (roll, pitch, yaw in rad); innovations wrapped."""

import numpy as np

from . import complex_step
from .fusion import Innovation, fuse
from .imu_model import euler_zyx, wrap_angle

SOURCE = "imu_angle"
LABELS = ("roll", "pitch", "yaw")
UNIT = "rad"


def predict(ekf, x):
    """Predicted Z-Y-X angles (3,) rad and their Jacobian (3, n)."""
    L = ekf.layout
    cols = ekf.position_columns
    N, N_dot = ekf.batch_nodes(complex_step.perturbed(x, cols))
    R_ws, _ = ekf.imu.frame(N, N_dot)
    value, J = complex_step.split(euler_zyx(R_ws))
    H = np.zeros((3, L.size))
    H[:, cols] = J
    return value, H


def angle_residual(z, hx):
    return wrap_angle(z - hx)


def fuse_angle(ekf, euler_rad) -> Innovation:
    """Fuse one Z-Y-X angle sample (3,) rad taken at the filter's current time."""
    hx, H = predict(ekf, ekf.x)
    R = np.eye(3) * ekf.config.imu_angle_std_rad**2
    return fuse(ekf, SOURCE, np.asarray(euler_rad, float), hx, H, R, angle_residual)
