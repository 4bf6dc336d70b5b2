"""The attitude of a structure: the rotation of a body frame that four of its nodes define.

A tensegrity has no rigid body whose orientation is *the* attitude: its bars turn against each
other as the strings change. A scene therefore names the nodes of its body frame
(``[attitude] frame = ["a", "b", "c", "d"]``, docs/scene-format.md):

- ``e_x`` along a -> b,
- ``e_y`` along c -> d, made orthogonal to ``e_x`` (Gram-Schmidt),
- ``e_z = e_x x e_y``.

``F = [e_x e_y e_z]`` (columns, world axes) is the frame of node positions ``N``; ``F0`` that of
the scene's initial positions. The **attitude** is ``A = F0^T F``: the frame's rotation from its
start, written in the start frame's axes, so that it is independent of where the structure
starts and of translations. Its angles are roll, pitch and yaw in the intrinsic Z-Y'-X''
(aerospace) convention, ``A = Rz(yaw) Ry(pitch) Rx(roll)``: yaw about the start frame's z, pitch
about the y' that yaw left, roll about the final x''. Its quaternion is ``(w, x, y, z)``, scalar
first, with ``w >= 0`` (the rotation angle in [0, pi]).

Near pitch +-90 degrees roll and yaw turn about the same axis and only their difference (or sum)
is defined: there roll is set to zero and the whole turn given to yaw, so no angle is ever NaN.
"""

from dataclasses import dataclass

import numpy as np

from .errors import SceneError

GIMBAL_COS = 1e-9
"""``cos(pitch)`` below which roll and yaw are not separable (round-off in the matrix, about
1e-16, would split them at random): roll is set to 0 and yaw takes the whole turn. The rotation
the angles give then differs from ``A`` by at most about this angle, rad."""


def cross(a, b):
    """Cross product along the last axis (np.cross's argument checks cost more than the product
    on the small batches of a planner or a log)."""
    return np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


def pair_frame(N, cols):
    """Frame of two node pairs: ``e_x`` along ``cols[0] -> cols[1]``, ``e_y`` along
    ``cols[2] -> cols[3]`` made orthogonal to ``e_x``, ``e_z = e_x x e_y``.

    Parameters
    ----------
    N : ndarray, shape (..., 3, n), m
        Node positions (a batch of them: any leading dimensions).
    cols : sequence of 4 int
        Columns of the four nodes in ``N``.

    Returns
    -------
    F : ndarray, shape (..., 3, 3)
        Columns ``e_x, e_y, e_z`` (unit vectors, world frame).
    """
    a, b, c, d = (N[..., :, i] for i in cols)
    ex = b - a
    ex = ex / np.linalg.norm(ex, axis=-1, keepdims=True)
    ey = d - c
    ey = ey - np.sum(ey * ex, axis=-1, keepdims=True) * ex
    ey = ey / np.linalg.norm(ey, axis=-1, keepdims=True)
    return np.stack([ex, ey, cross(ex, ey)], axis=-1)


def euler_zyx(R):
    """Roll, pitch, yaw (intrinsic Z-Y'-X'', ``R = Rz(yaw) Ry(pitch) Rx(roll)``) of rotations
    ``R`` (..., 3, 3), shape (..., 3), rad; at gimbal lock (:data:`GIMBAL_COS`) roll is 0."""
    R = np.asarray(R, float)
    cos_pitch = np.hypot(R[..., 0, 0], R[..., 1, 0])
    pitch = np.arctan2(-R[..., 2, 0], cos_pitch)  # arcsin(-R20) loses half the digits near +-90
    roll = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    yaw = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    locked = cos_pitch < GIMBAL_COS
    roll = np.where(locked, 0.0, roll)
    yaw = np.where(locked, np.arctan2(-R[..., 0, 1], R[..., 1, 1]), yaw)
    return np.stack([roll, pitch, yaw], axis=-1)


def _products_map():
    """``(E, T)`` such that ``E + R.reshape(9) @ T``, reshaped (4, 4), is ``4 q q^T`` of the
    rotation ``R`` with quaternion ``q = (w, x, y, z)``: ``4 w^2 = 1 + R00 + R11 + R22``,
    ``4 w x = R21 - R12``, ``4 x y = R01 + R10``, and so on."""
    terms = {  # (i, j) of 4 q q^T -> {(row, col) of R: coefficient}
        (0, 0): {(0, 0): 1, (1, 1): 1, (2, 2): 1},
        (1, 1): {(0, 0): 1, (1, 1): -1, (2, 2): -1},
        (2, 2): {(0, 0): -1, (1, 1): 1, (2, 2): -1},
        (3, 3): {(0, 0): -1, (1, 1): -1, (2, 2): 1},
        (0, 1): {(2, 1): 1, (1, 2): -1},
        (0, 2): {(0, 2): 1, (2, 0): -1},
        (0, 3): {(1, 0): 1, (0, 1): -1},
        (1, 2): {(0, 1): 1, (1, 0): 1},
        (1, 3): {(0, 2): 1, (2, 0): 1},
        (2, 3): {(1, 2): 1, (2, 1): 1},
    }
    T = np.zeros((9, 4, 4))
    for (i, j), entries in terms.items():
        for (r, c), coefficient in entries.items():
            T[3 * r + c, i, j] = T[3 * r + c, j, i] = coefficient
    return np.eye(4).ravel(), T.reshape(9, 16)


_E, _T = _products_map()


def quaternion_from_matrix(R):
    """Unit quaternions ``(w, x, y, z)``, shape (..., 4), ``w >= 0``, of rotations ``R``
    (..., 3, 3).

    The diagonal of ``4 q q^T`` fixes each component's square; the row of the largest (well
    away from zero) gives the quaternion up to its norm (Shepperd's choice, accurate at every
    angle, also at half turns where ``w = 0``).
    """
    R = np.asarray(R, float)
    products = (_E + R.reshape(*R.shape[:-2], 9) @ _T).reshape(*R.shape[:-2], 4, 4)
    k = np.argmax(np.diagonal(products, axis1=-2, axis2=-1), axis=-1)
    row = np.take_along_axis(products, k[..., None, None], axis=-2)[..., 0, :]
    q = row / np.linalg.norm(row, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


def angle_between(q_a, q_b):
    """Rotation angle, rad, in [0, pi], between attitudes of unit quaternions ``q_a`` and
    ``q_b`` (..., 4): the geodesic distance of the two rotations, twice the angle between the
    quaternions once ``q_b`` takes the sign nearer ``q_a``, ``4 atan2(|a - b|, |a + b|)``
    (accurate also near zero, where ``2 acos <a, b>`` loses half the digits)."""
    a, b = np.asarray(q_a, float), np.asarray(q_b, float)
    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)
    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))


@dataclass(frozen=True)
class Attitude:
    """The attitude of one set of node positions (or a batch: leading dimensions).

    Attributes
    ----------
    rotation : ndarray, shape (..., 3, 3)
        ``A = F0^T F``, the body frame's rotation from its start in the start frame's axes.
    quaternion : ndarray, shape (..., 4)
        ``(w, x, y, z)`` of ``A``, ``w >= 0``.
    rpy_rad : ndarray, shape (..., 3), rad
        Roll, pitch, yaw of ``A`` (intrinsic Z-Y'-X'').
    """

    rotation: np.ndarray
    quaternion: np.ndarray
    rpy_rad: np.ndarray


class BodyFrame:
    """The body frame a scene's ``[attitude]`` table names, and the attitude it gives.

    Positions ``N`` are in the scene's node order (3, n_scene), as the run's logs hold them;
    :meth:`of_model` measures a model's node matrices instead (``model.nodes(x)``, virtual nodes
    included, ordered by bars).

    Parameters
    ----------
    scene : Scene
        A scene with an ``[attitude]`` table (``scene.attitude_frame``).
    columns : sequence of 4 int, optional
        Columns of the frame's nodes in the positions to be measured (default: scene order).

    Raises
    ------
    SceneError
        The scene has no ``[attitude]`` table.
    """

    def __init__(self, scene, columns=None):
        if scene.attitude_frame is None:
            raise SceneError(f"{scene.source}: attitude: no [attitude] table (no body frame)")
        self.nodes = tuple(scene.attitude_frame)
        self.F0 = pair_frame(scene.positions, [scene.node_index(n) for n in self.nodes])
        self.cols = [scene.node_index(n) for n in self.nodes] if columns is None else columns

    @classmethod
    def of_model(cls, model) -> "BodyFrame":
        """The body frame of ``model``'s scene, measured on its node matrices (3, n_model)."""
        primary = model.structure.primary
        return cls(model.scene, [primary[n] for n in model.scene.attitude_frame or ()])

    def rotation(self, N):
        """``A = F0^T F`` (..., 3, 3) of node positions ``N`` (..., 3, n), m."""
        return np.einsum("ji,...jk->...ik", self.F0, pair_frame(np.asarray(N, float), self.cols))

    def attitude(self, N) -> Attitude:
        """The :class:`Attitude` of node positions ``N`` (..., 3, n), m."""
        A = self.rotation(N)
        return Attitude(A, quaternion_from_matrix(A), euler_zyx(A))


def attitude_of(scene, positions) -> Attitude:
    """The attitude of ``scene``'s body frame at node positions ``positions`` (..., 3, n_scene),
    m (scene node order): one-off use; build a :class:`BodyFrame` once to measure many."""
    return BodyFrame(scene).attitude(positions)
