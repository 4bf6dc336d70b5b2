"""The attitude of any free scene whose actuated strings change its shape and whose wheels
change speed: the three-axis planner's model (``f(t, x, u, params)``, complex-step safe).

State ``x = [q (4) | r (a) | omega_w (n_w) | dH (3, only with lost reactions)]``: the body
frame's attitude quaternion (its rotation from its start, :mod:`gyrotensegrity.attitude`), the
actuated strings' coordinates (their rest lengths, m; the D-bar's one coordinate is its n1-n3
rest length, the n2-n4 string follows), the wheels' spins, rad/s, and the momentum the wheels'
lost reactions took away (below). Input ``u = [r_dot (a) | omega_w_dot (n_w)]``: servo rates,
m/s, and wheel accelerations, rad/s^2, so that the servo speed and the wheel acceleration are
boxes on ``u`` and the servo range and wheel speed boxes on ``x``.

The shape is quasi-static (:mod:`.shape`): the equilibrium of the current rest lengths, in the
body frame. Nothing outside acts, so the total angular momentum ``H`` (the start frame's axes) is
``H0`` (the only parameter) but for the wheels whose motor reaction leaves the structure
(:mod:`.wheel_reaction`, ``lost``): their momentum change ``dH`` is three more states. With
``R(q)`` the attitude, in body axes::

    R^T (H0 + dH) = I_b(r) w + h_b(r) omega_w + B_b(r) r_dot
    w = I_b^-1 (R^T (H0 + dH) - h_b omega_w - B_b r_dot),  q_dot = q * (0, w) / 2
    dH_dot = R h_b[lost] omega_w_dot[lost]

so that a ``lost`` wheel's acceleration changes ``H`` and ``h_b omega_w`` alike and turns nothing;
it acts only through its spin, when the shape moves its axis (the gyroscopic couple). A wheel
whose reaction only spins its own bar (``own``) keeps its bar's axial momentum: the planner holds
it (:attr:`AttitudeModel.steerable`), and held it is exact.

(:mod:`.shape_table` for the terms). Frozen rest lengths give :func:`.attitude_model.rhs`.
The function works on batches (leading dimensions of ``x`` and ``u``), so that a planner
integrates all its complex-step copies at once.
"""

import numpy as np

from gyrotensegrity import BodyFrame

from .attitude_model import check_free, params_at, quaternion_product, rotation_of
from .errors import PlanError
from .reduced import DBarReduced
from .schedule import Limits
from .shape import RhombusShape, StaticShape
from .shape_table import ShapeTable
from .wheel_reaction import coupling_mask, wheel_couplings

TABLE_POINTS = {0: 1, 1: 81, 2: 15, 3: 9}
"""Grid points per coordinate of the shape table, by the number of coordinates (the tensor
grid's cost grows as the power; :meth:`ShapeTable.interpolation_error` measures what each
gives)."""


def scheduled_strings(model):
    """Names of the strings whose rest length the scene schedules (the actuated ones)."""
    return tuple(
        s.name
        for s, schedule in zip(model.scene.strings, model.rest_schedules, strict=True)
        if np.ptp(schedule.value) > 0.0
    )


def shape_of(model, strings, limits, travel_m):
    """The shape provider: the D-bar's rhombus when ``strings`` are its two diagonals, else
    the static equilibrium of any scene."""
    try:
        dbar = DBarReduced(model)
        diagonals = {model.scene.strings[i].name for i in (dbar.i13, dbar.i24)}
    except PlanError:
        diagonals = None
    if diagonals is not None and set(strings) == diagonals:
        return RhombusShape(model, limits)
    return StaticShape(model, strings, limits, travel_m)


class AttitudeModel:
    """The reduced attitude model of a free scene (see the module docstring).

    Parameters
    ----------
    model : gyrotensegrity.Model
    strings : sequence of str, optional
        Actuated strings (default: those the scene schedules).
    limits : Limits, optional
        Servo ranges (the coordinates' box) and speed.
    travel_m : float, m, optional
        How far a string may leave its rest length (default 0.1 m); the box shrinks further
        where strings would go slack.
    points : int, optional
        Grid points per coordinate (default :data:`TABLE_POINTS`).
    """

    def __init__(self, model, strings=None, limits=None, travel_m=0.1, points=None):
        check_free(model)
        self.model = model
        self.frame = BodyFrame.of_model(model)
        self.limits = limits or Limits()
        strings = scheduled_strings(model) if strings is None else tuple(strings)
        self.shape = shape_of(model, strings, self.limits, travel_m)
        self.names = self.shape.names
        self.a, self.n_w = len(self.shape.rest), len(model.wheel_bars)
        if self.a not in TABLE_POINTS:
            raise PlanError(f"the planner tabulates at most 3 actuated strings, got {self.a}")
        points = TABLE_POINTS[self.a] if points is None else points
        self.table = ShapeTable(model, self.shape, points, self.frame.F0)
        self.wheels = tuple(model.scene.bars[i].name for i in model.wheel_bars)
        self.couplings = wheel_couplings(model)
        self.lost = coupling_mask(self.couplings, "lost")
        self.steerable = ~coupling_mask(self.couplings, "own")
        self.n_h = 3 if self.lost.any() else 0
        self.wheel_gain = 1.0
        """Factor on the wheels' momentum (a closed loop's fitted gain: the truth's wheels
        heavier or lighter than the scene's)."""

    @property
    def size(self):
        """``(n_x, n_u)``."""
        return 4 + self.a + self.n_w + self.n_h, self.a + self.n_w

    def split(self, x):
        """``(q, r, omega_w)`` of states ``x`` (..., n_x)."""
        a, n_w = self.a, self.n_w
        return x[..., :4], x[..., 4 : 4 + a], x[..., 4 + a : 4 + a + n_w]

    def momentum(self, x, H0):
        """The total angular momentum (..., 3), start frame's axes, at states ``x``."""
        if not self.n_h:
            return np.broadcast_to(H0, x.shape[:-1] + (3,))
        return H0 + x[..., -3:]

    def terms(self, r):
        """``(I_b, h_b, B_b, L)`` at coordinates ``r`` (..., a) (:mod:`.shape_table`)."""
        return self.table.split(self.table(r))

    def body_rate(self, x, u, H0):
        """Angular velocity (..., 3) rad/s, body axes, of states ``x`` under inputs ``u``."""
        return self._rate(x, u, H0)[0]

    def _rate(self, x, u, H0):
        """The body rate and ``h_b`` (..., 3, n_w) at states ``x``."""
        q, r, omega_w = self.split(x)
        I_b, h_b, B_b, _ = self.terms(r)
        h_b = self.wheel_gain * h_b  # the wheels' momentum, also what a lost reaction carries
        H_b = np.einsum("...ji,...j->...i", rotation_batch(q), self.momentum(x, H0))
        rhs = H_b - np.einsum("...ij,...j->...i", h_b, omega_w)
        rhs = rhs - np.einsum("...ij,...j->...i", B_b, u[..., : self.a])
        return np.linalg.solve(I_b, rhs[..., None])[..., 0], h_b

    def rhs(self, t, x, u, H0):
        """``dx/dt`` (..., n_x) of states ``x`` (..., n_x) under inputs ``u`` (..., n_u);
        ``H0`` (3,) kg m^2/s, the start frame's axes; ``t`` unused (nothing depends on it)."""
        w, h_b = self._rate(x, u, H0)
        zero = np.zeros(w.shape[:-1] + (1,), dtype=w.dtype)
        q_dot = 0.5 * quaternion_product_batch(x[..., :4], np.concatenate([zero, w], axis=-1))
        parts = [q_dot, u]
        if self.n_h:  # the lost reactions' momentum, start frame's axes
            spin_up = u[..., self.a :][..., self.lost]
            lost = np.einsum("...ij,...j->...i", h_b[..., self.lost], spin_up)
            parts.append(np.einsum("...ij,...j->...i", rotation_batch(x[..., :4]), lost))
        return np.concatenate(parts, axis=-1)

    def start(self, x_full, t_s=0.0, rest=None):
        """``(x0, H0)`` of a full model state ``x_full`` at ``t_s`` (s): its attitude, the
        coordinates ``rest`` (default the scene's at ``t_s``), its spins and momentum."""
        m = self.model
        u = m.input_at(t_s)
        N, _ = m.nodes(x_full)
        q = self.frame.attitude(N).quaternion
        r = self.shape.rest if rest is None else np.asarray(rest, float)
        H0 = params_at(m, x_full, u).H0
        return np.concatenate([q, r, m.wheel_speeds(x_full, u), np.zeros(self.n_h)]), H0


def quaternion_product_batch(p, q):
    """Hamilton products ``p q`` (..., 4) of quaternions (..., 4), w first."""
    return np.moveaxis(quaternion_product(np.moveaxis(p, -1, 0), np.moveaxis(q, -1, 0)), 0, -1)


def rotation_batch(q):
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4), w first."""
    return np.moveaxis(rotation_of(np.moveaxis(q, -1, 0)), (0, 1), (-2, -1))
