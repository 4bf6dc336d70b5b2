"""IMU specific force: ``z = R_ws^T (a_imu - g) + b_a`` (m/s^2, sensor axes; ``b_a`` the
accelerometer's bias where it is a state, else folded into the noise).

The acceleration of the IMU point comes from the dynamics (it depends on the input ``u``); its
Jacobian comes from the batched complex-step evaluation of :mod:`.imu_prediction`.
"""

import numpy as np

from .fusion import Measurement
from .imu_prediction import ImuPrediction, at_sample_time, full_jacobian, timing_noise

SOURCE = "imu_accel"
LABELS = ("x", "y", "z")


def measurement(ekf, pred: ImuPrediction, accel_m_s2) -> Measurement:
    """The specific-force sample (3,) m/s^2 with its prediction and Jacobian (3, n)."""
    L = ekf.layout
    H = full_jacobian(ekf, pred.d_specific_force)
    H[:, L.accel_bias] = np.eye(3)[:, : L.n_accel_bias]
    R = timing_noise(ekf, pred, pred.d_specific_force, ekf.config.imu_accel_std_m_s2)
    hx = at_sample_time(ekf, pred, pred.d_specific_force, pred.specific_force)
    hx = hx + ekf.x[L.accel_bias] if L.n_accel_bias else hx
    return Measurement(SOURCE, np.asarray(accel_m_s2, float), hx, H, R)
