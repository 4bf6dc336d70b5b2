"""Attitude of the D-bar plane from node positions.

Plane frame (all vectors in the world frame, shape (3,)):

- ``e_x`` along n1 -> n3 (the actuated diagonal),
- ``e_y`` along n4 -> n2, made orthogonal to ``e_x``,
- ``e_z = e_x x e_y``, the plane normal.

The *tilt* is the rotation of the plane normal about a fixed world axis ``a``, the *tilt axis*:
the direction of the wheels' angular momentum at the start, which is the n2-n4 axis for the
paper's spin pattern (+, -, -, +). Shortening n1-n3 makes the wheel momentum along ``a`` grow,
so the structure turns about ``a`` to conserve the total angular momentum (field notes,
section 1). With ``n0`` the initial normal and ``p`` the normal projected onto the plane
perpendicular to ``a``::

    tilt = atan2(((n0 x p) . a), n0 . p)      rad, in (-pi, pi]

A rotation of the whole structure by ``+phi`` about ``a`` gives ``tilt = +phi``.

The D-bar is a plug-in of the run, the planner and the plots: :func:`attitude_of` gives a scene's
attitude measure, ``None`` for a scene without the plane nodes (a prism), which then runs and
plots with node positions and the estimate only.

Any scene whose file names a body frame (``[attitude]``) also has a three-axis attitude, the
frame's rotation from its start (:func:`body_frame_of`, :mod:`gyrotensegrity.attitude`); for the
D-bar's frame (x along n1 -> n3, y along n4 -> n2) a rotation about the n2-n4 axis is a tilt and
a pitch of the same angle.
"""

import numpy as np

from gyrohost.geometry import plane_frame, tilt_angle
from gyrotensegrity import BodyFrame

from .errors import PlanError

PLANE_NODES = ("n1", "n2", "n3", "n4")
"""The D-bar's plane nodes, the one definition: n1-n3 the actuated diagonal, n2-n4 the other."""


def node_columns(model, names=PLANE_NODES):
    """Columns of the primary nodes ``names`` in the model's node matrix, list of int."""
    primary = model.structure.primary
    missing = [n for n in names if n not in primary]
    if missing:
        raise PlanError(f"scene {model.scene.name}: no node(s) {', '.join(missing)}")
    return [primary[n] for n in names]


class Attitude:
    """Tilt of the D-bar plane for one model (fixes the tilt axis and the reference normal).

    Parameters
    ----------
    model : gyrotensegrity.Model
        A scene with nodes n1..n4 (the D-bar).
    N0 : ndarray, shape (3, n), m, optional
        Reference node positions (default: the scene's initial positions).
    axis : ndarray, shape (3,), optional
        Tilt axis, world frame (default: the plane's ``e_y`` at ``N0``, the n2-n4 axis).
    """

    def __init__(self, model, N0=None, axis=None):
        self.cols = node_columns(model)
        N0 = model.structure.N0 if N0 is None else np.asarray(N0, float)
        R0 = plane_frame(N0, self.cols)
        self.normal0 = R0[:, 2]
        self.axis = R0[:, 1] if axis is None else np.asarray(axis, float) / np.linalg.norm(axis)

    def frame(self, N):
        """Plane frame ``R`` (3, 3) of node positions ``N`` (3, n), m."""
        return plane_frame(N, self.cols)

    def tilt(self, N):
        """Tilt (rad) of node positions ``N`` (3, n), m."""
        return tilt_angle(self.frame(N)[:, 2], self.axis, self.normal0)

    def tilt_rate(self, N, N_dot):
        """Tilt rate (rad/s) of positions ``N`` moving with ``N_dot`` (both (3, n), m and m/s).

        A central difference of :meth:`tilt` along ``N_dot`` (nodes moved by about 1e-7 m).
        """
        eps = 1e-7
        h = eps / max(float(np.max(np.abs(N_dot))), 1e-12)
        return (self.tilt(N + h * N_dot) - self.tilt(N - h * N_dot)) / (2.0 * h)

    def n13(self, N):
        """Distance n1-n3 (m) of node positions ``N`` (3, n), m."""
        return float(np.linalg.norm(N[:, self.cols[2]] - N[:, self.cols[0]]))


def has_plane(model) -> bool:
    """Whether ``model``'s scene has the D-bar's plane nodes :data:`PLANE_NODES`."""
    return all(n in model.structure.primary for n in PLANE_NODES)


class TiltMeter:
    """Tilt of the D-bar plane from scene node positions (as the planner measures it).

    Parameters
    ----------
    model : gyrotensegrity.Model
        A scene with the plane nodes; fixes the tilt axis (the n2-n4 axis at rest) and the
        reference normal.
    """

    def __init__(self, model):
        self.attitude = Attitude(model)
        names = list(model.scene.node_names)
        self.cols = [names.index(n) for n in PLANE_NODES]

    def tilt(self, N_scene):
        """Tilt, rad, of scene node positions ``N_scene`` (3, n_scene), m: a float; of a batch
        (..., 3, n_scene) an array of the leading shape."""
        normal = plane_frame(N_scene, self.cols)[..., :, 2]
        return tilt_angle(normal, self.attitude.axis, self.attitude.normal0)


def body_frame_of(model) -> BodyFrame | None:
    """The body frame of ``model``'s scene (its ``[attitude]`` table), None without one."""
    return None if model.scene.attitude_frame is None else BodyFrame(model.scene)


def attitude_of(model) -> TiltMeter | None:
    """The attitude measure of ``model``'s scene: a :class:`TiltMeter` for a D-bar, else None."""
    return TiltMeter(model) if has_plane(model) else None
