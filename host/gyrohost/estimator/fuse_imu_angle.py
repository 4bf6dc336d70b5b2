"""IMU angles: ``z = euler_zyx(R_ws(eta2))`` (roll, pitch, yaw in rad); innovations wrapped.

The Jacobian of the Z-Y-X angles follows from the Jacobian of ``R_ws`` by the chain rule
(roll = atan2(R21, R22), pitch = -asin(R20), yaw = atan2(R10, R00)).
"""

import numpy as np

from gyrohost.geometry import wrap_angle

from .fusion import Measurement
from .imu_prediction import ImuPrediction, at_sample_time, full_jacobian, timing_noise

SOURCE = "imu_angle"
LABELS = ("roll", "pitch", "yaw")


def angles_and_jacobian(R, dR):
    """Z-Y-X angles (3,) rad of ``R`` (3, 3) and their Jacobian from dR (9, k), shape (3, k)."""

    def d(i, j):
        return dR[3 * i + j]

    def atan2_grad(y, x, dy, dx):
        return (x * dy - y * dx) / (x * x + y * y)

    angles = np.array(
        [np.arctan2(R[2, 1], R[2, 2]), -np.arcsin(R[2, 0]), np.arctan2(R[1, 0], R[0, 0])]
    )
    J = np.stack(
        [
            atan2_grad(R[2, 1], R[2, 2], d(2, 1), d(2, 2)),
            -d(2, 0) / np.sqrt(1.0 - R[2, 0] ** 2),
            atan2_grad(R[1, 0], R[0, 0], d(1, 0), d(0, 0)),
        ]
    )
    return angles, J


def angle_residual(z, hx):
    return wrap_angle(z - hx)


def measurement(ekf, pred: ImuPrediction, euler_rad) -> Measurement:
    """The angle sample (3,) rad with its prediction and Jacobian (3, n)."""
    hx, J = angles_and_jacobian(pred.R_ws, pred.dR_ws)
    hx = at_sample_time(ekf, pred, J, hx)
    R = timing_noise(ekf, pred, J, ekf.config.imu_angle_std_rad)
    z = np.asarray(euler_rad, float)
    return Measurement(SOURCE, z, hx, full_jacobian(ekf, J), R, angle_residual)
