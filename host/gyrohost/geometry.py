"""Rotations and plane frames shared by the estimator, the rig and the planner.

Conventions: Z-Y-X Euler angles (roll about x, pitch about y, yaw about z, rad), as the
BWT61CL reports them and as a scene's attitude gives them (``euler_zyx`` and the frame of two
node pairs come from :mod:`gyrotensegrity.attitude`); rotation matrices map body (or sensor)
axes to world axes, shape (3, 3).
"""

import numpy as np

from gyrotensegrity.attitude import cross, pair_frame
from gyrotensegrity.attitude import euler_zyx as euler_zyx


def rotation_zyx(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rotation matrix ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``, shape (3, 3); angles in rad."""
    cr, sr, cp, sp, cy, sy = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                              np.cos(yaw), np.sin(yaw))  # fmt: skip
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def turn_from_first(R: np.ndarray) -> np.ndarray:
    """How far each rotation of ``R`` (k, 3, 3) has turned from the first, rad, shape (k,): the
    angle of ``R[0]^T R[i]``."""
    cos_turn = (np.einsum("ji,kji->k", R[0], R) - 1.0) / 2.0
    return np.arccos(np.clip(cos_turn, -1.0, 1.0))


def wrap_angle(a):
    """Angles wrapped into [-pi, pi), rad (any shape)."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def plane_frame(N, cols):
    """Frame of a plane spanned by four nodes (the D-bar's rhombus), shape (..., 3, 3): ``e_x``
    along node 0 -> node 2 of ``cols``, ``e_y`` along node 3 -> node 1 made orthogonal to
    ``e_x``, ``e_z = e_x x e_y`` the plane normal (:func:`gyrotensegrity.attitude.pair_frame`
    of the pairs (0, 2) and (3, 1); ``N`` (..., 3, n), m, any leading dimensions)."""
    return pair_frame(N, (cols[0], cols[2], cols[3], cols[1]))


def tilt_angle(normal, axis, normal0):
    """Signed rotation (rad) of ``normal`` (..., 3) about ``axis`` away from ``normal0`` (both
    (3,)): a float for one normal, an array of the leading shape for a batch."""
    axis = axis / np.linalg.norm(axis)
    p = normal - (normal @ axis)[..., None] * axis
    angle = np.arctan2(cross(normal0, p) @ axis, p @ normal0)
    return float(angle) if np.ndim(angle) == 0 else angle


def levelling_rotvec(up):
    """Rotation vector (..., 3), rad, world axes, of the smallest rotation that turns the unit
    vectors ``up`` (..., 3) onto the world's z axis: about a horizontal axis (its z component
    is 0), by the angle between them. Smooth in ``up`` except exactly upside down, where the
    axis is undefined and zero is returned.

    It compares attitudes without Euler angles (whose roll and yaw are singular at pitch +-90
    degrees) and without yaw (relative on the IMU): ``up = R_a R_b^T z`` is the attitude
    ``R_b``'s up direction seen in ``R_a``'s world, and its levelling rotation is, to first
    order, the horizontal part of ``log(R_b R_a^T)`` in ``R_a``'s world.
    """
    up = np.asarray(up, float)
    axis = np.stack([up[..., 1], -up[..., 0], np.zeros(up.shape[:-1])], axis=-1)  # up x z
    s = np.linalg.norm(axis, axis=-1, keepdims=True)
    angle = np.arctan2(s, up[..., 2:3])
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(s > 1e-12, angle / s, np.where(up[..., 2:3] > 0.0, 1.0, 0.0))
    return axis * scale


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """Rotation vector (3,) rad of the rotation ``R`` (3, 3), angle in [0, pi]: by its unit
    quaternion, built from the largest of ``1 + trace`` and ``1 - trace + 2 R_ii`` (Shepperd's
    choice, no division by a small number), then ``angle / sin(angle / 2)`` times its vector
    part (a series below 1e-3 rad, where that ratio loses digits). The same choice as the
    batched :func:`gyrotensegrity.attitude.quaternion_from_matrix`, written for one matrix: the
    fast filter takes one per IMU sample, and the batched form costs it twice as long."""
    trace = R[0, 0] + R[1, 1] + R[2, 2]
    i = int(np.argmax(np.diag(R)))
    if trace >= R[i, i]:
        q = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1], 1.0 + trace])
    else:
        j, k = (i + 1) % 3, (i + 2) % 3
        q = np.empty(4)
        q[i] = 1.0 - trace + 2.0 * R[i, i]
        q[j] = R[j, i] + R[i, j]
        q[k] = R[k, i] + R[i, k]
        q[3] = R[k, j] - R[j, k]
    q = q * (np.sign(q[3]) or 1.0) / np.sqrt(q @ q)
    sine = np.sqrt(q[:3] @ q[:3])
    angle = 2.0 * np.arctan2(sine, q[3])
    if angle <= 1e-3:
        scale = 2.0 + angle**2 / 12.0 + 7.0 * angle**4 / 2880.0
    else:
        scale = angle / np.sin(angle / 2.0)
    return scale * q[:3]
