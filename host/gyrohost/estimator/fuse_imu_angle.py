"""IMU angles as a rotation: the sample's Z-Y-X angles (roll, pitch, yaw, rad) turned into the
sensor axes ``R_m`` and compared with the predicted ``R_ws`` as a rotation vector in world axes,
``y = log(R_m R_ws^T)`` (rad).

Why not the angles themselves: the D-bar's manoeuvre takes the sensor's pitch through -90
degrees, where roll and yaw are singular. Their Jacobian grows as 1 / cos(pitch) (1.8e6 per
unit state near there) and one update then took the covariance to zero in a direction of the
node positions (a NEES of 1e6 at one step on the real-time rig). The rotation vector is smooth
everywhere: its Jacobian is ``vee(dR_ws R_ws^T)``, one column per state, never larger than the
frame's own derivative.

The angles' white noise (``imu_angle_std_rad`` each) maps into it through the Euler-rate matrix
``E`` (its columns the world axes of the roll, pitch and yaw rotations): ``sigma^2 E E^T``. At
pitch +-90 degrees roll and yaw turn about the same axis and ``E E^T`` loses a rank; a floor of
``(FLOOR * sigma)^2`` per axis keeps the innovation's covariance positive there. The sample's
time uncertainty adds ``imu_time_std_s^2 w w^T`` (``w`` the predicted angular velocity, world
axes), as for the other IMU measurements.
"""

import numpy as np
from scipy.spatial.transform import Rotation

from gyrohost.geometry import rotation_vector, rotation_zyx

from .fusion import Measurement
from .imu_prediction import ImuPrediction, full_jacobian

SOURCE = "imu_angle"
LABELS = ("x", "y", "z")
FLOOR = 0.1
"""Noise floor per world axis, as a fraction of ``imu_angle_std_rad`` (see module docstring)."""


def rotation_jacobian(R, dR):
    """World-axes rotation rates (3, k) of the sensor axes ``R`` (3, 3) per unit of each state,
    from ``dR`` (9, k): ``vee(dR_j R^T)``."""
    M = np.einsum("ijk,lj->ilk", dR.reshape(3, 3, -1), R)  # dR_j R^T, skew-symmetric
    return 0.5 * np.stack([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])


def euler_rate_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """World axes (columns, (3, 3)) about which a change of roll, pitch and yaw turns the Z-Y-X
    rotation: ``R_z(yaw) R_y(pitch) x``, ``R_z(yaw) y`` and ``z``."""
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    return np.array([[cy * cp, -sy, 0.0], [sy * cp, cy, 0.0], [-sp, 0.0, 1.0]])


def measurement(ekf, pred: ImuPrediction, euler_rad) -> Measurement:
    """The angle sample (3,) rad as a rotation vector (3,) rad with its Jacobian (3, n).

    The prediction is taken back to the sample's time when the filter is ``ekf.imu_lag_s``
    ahead of it: the sensor then stood turned back by ``w lag``.
    """
    J = rotation_jacobian(pred.R_ws, pred.dR_ws)
    w = J @ pred.x_dot  # angular velocity of the sensor axes, world axes, rad/s
    R_m = rotation_zyx(*np.asarray(euler_rad, float))
    turn = R_m @ pred.R_ws.T
    # scipy's Rotation costs more than the rest of this fusion; the fast path's log map is
    # equal to it to round-off (tests/test_geometry.py)
    log = rotation_vector(turn) if ekf.fast else Rotation.from_matrix(turn).as_rotvec()
    y = log + ekf.imu_lag_s * w
    c = ekf.config
    E = euler_rate_matrix(*euler_rad)
    R = c.imu_angle_std_rad**2 * (E @ E.T + FLOOR**2 * np.eye(3))
    R += c.imu_time_std_s**2 * np.outer(w, w)
    return Measurement(SOURCE, y, np.zeros(3), full_jacobian(ekf, J), R)
