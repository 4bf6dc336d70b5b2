"""IMU angular rate: ``z = omega_s(eta2, eta2_dot) + b_g`` (rad/s, sensor axes)."""

import numpy as np

from .fusion import Measurement
from .imu_prediction import ImuPrediction, at_sample_time, full_jacobian, timing_noise

SOURCE = "imu_rate"
LABELS = ("x", "y", "z")


def measurement(ekf, pred: ImuPrediction, omega_rad_s) -> Measurement:
    """The rate sample (3,) rad/s with its prediction and Jacobian (3, n)."""
    L = ekf.layout
    H = full_jacobian(ekf, pred.d_omega)
    H[:, L.bias] = np.eye(3)
    R = timing_noise(ekf, pred, pred.d_omega, ekf.config.imu_rate_std_rad_s)
    hx = at_sample_time(ekf, pred, pred.d_omega, pred.omega) + ekf.x[L.bias]
    return Measurement(SOURCE, np.asarray(omega_rad_s, float), hx, H, R)
