"""Where the IMU sits on the structure and what it measures (batched, complex-step-safe).

The attachment is the rig's (``gyrohost.simrig.truth``): three scene nodes ``imu_frame_nodes =
[a, b, c]`` give the body frame, ``x`` along a -> b, ``z`` along ``x cross (c - a)``, ``y = z cross
x``; the IMU point is the midpoint of a and b. The sensor axes are the body axes turned by
``imu_mounting_rpy_rad`` (Z-Y-X), corrected by the mounting state ``d_mount`` where the filter has
one (the angles ``imu_mounting_rpy_rad + d_mount``). Measurements:

- angular rate of the sensor axes, in sensor axes (rad/s), plus the gyro bias state;
- specific force ``R^T (a - g)`` in sensor axes (m/s^2), ``g = imu_gravity_m_s2`` (world frame;
  the sensor feels gravity even where the scene leaves it out because supports cancel it);
- Z-Y-X Euler angles (roll, pitch, yaw) of the sensor axes in the world frame (rad).
"""

import numpy as np

from gyrohost.geometry import rotation_zyx

from .complex_step import atan2
from .errors import EstimatorConfigError

_NEXT, _PREV = [1, 2, 0], [2, 0, 1]


def _cross(a, b):
    """Cross product along axis 1 of (K, 3) arrays (complex-safe, no conjugation)."""
    return a[:, _NEXT] * b[:, _PREV] - a[:, _PREV] * b[:, _NEXT]


def _dot(a, b):
    return (a * b).sum(axis=1, keepdims=True)


MIN_FRAME_SINE = 0.01
"""The smallest sine of the angle at the IMU frame's first node (why: ``ImuGeometry``'s
plane check)."""


class ImuGeometry:
    """The IMU's frame and point as functions of node positions.

    Parameters
    ----------
    model : gyrotensegrity.Model
    config : EstimatorConfig
    """

    def __init__(self, model, config):
        primary = model.structure.primary

        def index(key, names):
            for name in names:
                if name not in primary:
                    raise EstimatorConfigError(
                        f"estimator key '{key}': node {name!r} is not in scene "
                        f"{model.scene.name!r} (nodes: {', '.join(primary)})"
                    )
            return np.array([primary[n] for n in names])

        self.a, self.b, self.c = index("imu_frame_nodes", config.imu_frame_nodes)
        self._check_spans_a_plane(model, config.imu_frame_nodes)
        self.rpy_rad = np.asarray(config.imu_mounting_rpy_rad, float)
        self.R_bs = rotation_zyx(*self.rpy_rad)  # sensor axes in body axes
        self.gravity = np.asarray(config.imu_gravity_m_s2, float)

    def _check_spans_a_plane(self, model, names) -> None:
        """The frame's z axis is the normal of its three nodes' plane, which turns by a node's
        error over its distance divided by the sine of their angle: below 0.01, a millimetre
        on a 10 cm frame turns it by a radian, and the attitude means nothing."""
        N0 = model.structure.N0
        ab, ac = N0[:, self.b] - N0[:, self.a], N0[:, self.c] - N0[:, self.a]
        sine = np.linalg.norm(np.cross(ab, ac)) / max(
            np.linalg.norm(ab) * np.linalg.norm(ac), 1e-300
        )
        if sine < MIN_FRAME_SINE:
            raise EstimatorConfigError(
                f"estimator key 'imu_frame_nodes': {list(names)} lie on a line in scene "
                f"{model.scene.name!r} (sine of their angle {sine:.2g}, below {MIN_FRAME_SINE})"
            )

    def mounting(self, d_mount_rad):
        """Sensor axes in body axes (3, 3) of the configured mounting corrected by
        ``d_mount_rad`` (3,) rad, and their derivatives by the three corrections (3, 3, 3),
        ``[k]`` by roll, pitch, yaw: ``R = Rz Ry Rx`` gives ``R [e_x]``, ``[Rz e_y] R``,
        ``[e_z] R`` (``[v]`` the cross-product matrix of ``v``)."""
        roll, pitch, yaw = self.rpy_rad + np.asarray(d_mount_rad)  # complex-step safe
        R = rotation_zyx(roll, pitch, yaw)
        axes = (np.array([-np.sin(yaw), np.cos(yaw), 0.0]), np.array([0.0, 0.0, 1.0]))
        dR = np.stack([R @ _hat(np.array([1.0, 0.0, 0.0])), _hat(axes[0]) @ R, _hat(axes[1]) @ R])
        return R, dR

    def frame(self, N, N_dot, R_bs=None):
        """Sensor axes in the world and the sensor's angular rate.

        Parameters
        ----------
        N, N_dot : ndarray, shape (K, 3, n), m and m/s
        R_bs : ndarray, shape (3, 3), optional
            Sensor axes in body axes (default: the configured mounting's).

        Returns
        -------
        R_ws : ndarray, shape (K, 3, 3)
            Columns: sensor x, y, z axes in world coordinates.
        omega_s : ndarray, shape (K, 3), rad/s
            Angular rate in sensor axes.
        """
        d1 = N[:, :, self.b] - N[:, :, self.a]
        d2 = N[:, :, self.c] - N[:, :, self.a]
        d1_dot = N_dot[:, :, self.b] - N_dot[:, :, self.a]
        d2_dot = N_dot[:, :, self.c] - N_dot[:, :, self.a]
        len1 = np.sqrt(_dot(d1, d1))
        ex = d1 / len1
        ex_dot = (d1_dot - ex * _dot(ex, d1_dot)) / len1
        c = _cross(d1, d2)
        c_dot = _cross(d1_dot, d2) + _cross(d1, d2_dot)
        len_c = np.sqrt(_dot(c, c))
        ez = c / len_c
        ez_dot = (c_dot - ez * _dot(ez, c_dot)) / len_c
        ey = _cross(ez, ex)
        # omega_b = vee(R^T R_dot) = (ez . ey_dot, ex . ez_dot, ey . ex_dot);
        # ez . ey_dot = -ey . ez_dot since ey . ez = 0
        omega_b = np.concatenate([-_dot(ey, ez_dot), _dot(ex, ez_dot), _dot(ey, ex_dot)], axis=1)
        R_wb = np.stack([ex, ey, ez], axis=2)
        R_bs = self.R_bs if R_bs is None else R_bs
        return R_wb @ R_bs, omega_b @ R_bs

    def specific_force(self, R_ws, N_ddot):
        """Specific force at the IMU point in sensor axes, (K, 3), m/s^2."""
        a = 0.5 * (N_ddot[:, :, self.a] + N_ddot[:, :, self.b]) - self.gravity
        return np.einsum("kji,kj->ki", R_ws, a)


def _hat(v):
    """Cross-product matrix (3, 3) of ``v`` (3,): ``_hat(v) @ w = v x w``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def euler_zyx(R):
    """Roll, pitch, yaw (Z-Y-X) of a batch of rotations (K, 3, 3), shape (K, 3), rad."""
    roll = atan2(R[:, 2, 1], R[:, 2, 2])
    pitch = -np.arcsin(R[:, 2, 0])
    yaw = atan2(R[:, 1, 0], R[:, 0, 0])
    return np.stack([roll, pitch, yaw], axis=1)


def tilt(R):
    """Angle between the sensor z axis and the world z axis, rad; R shape (..., 3, 3)."""
    return np.arccos(np.clip(R[..., 2, 2], -1.0, 1.0))
