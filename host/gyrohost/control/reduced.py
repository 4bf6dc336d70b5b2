"""The planner's model of the D-bar: quasi-static shape, attitude from angular momentum.

The full model (``gyrotensegrity``) costs about 0.5 ms per right-hand side, so a 3 s run takes
seconds: too slow inside an optimiser that re-plans at a few hertz. This reduced model keeps
the physics that turns the plane and drops the fast string dynamics:

1. *Shape.* The D-bar is a rhombus of bar length ``l`` whose n1-n3 distance ``d`` equals the
   rest length of the actuated string (the strings are stiff and the n2-n4 string follows the
   rhombus geometry, so it neither pushes nor goes slack).
2. *Attitude.* No external torque acts, so the total angular momentum ``H`` is constant. With
   the structure turning as a rigid body about the tilt axis ``a`` (the n2-n4 axis) at rate
   ``w`` and a symmetric shape change (which carries no angular momentum)::

       a . H = I_a(d) w + h_w(d) . omega_w      =>      w = (a . H - h_w(d) . omega_w) / I_a(d)

   ``I_a(d)`` (kg m^2) is the locked inertia about ``a`` and ``h_w(d)`` (kg m^2, per wheel)
   the wheels' momentum along ``a`` per rad/s of spin. Both are evaluated with the full
   model's own mass properties (``gyrotensegrity.diagnostics.angular_momentum``: bar and wheel
   masses, ``J_t``, ``J_a``) on a table of shapes, then interpolated.

A whole horizon is one vectorised quadrature (tens of microseconds), so an optimiser can call
it thousands of times per plan. The gap to the full model (string stretch, lag of the shape
behind the rest length) is measured by validating plans with the accurate simulation.
"""

import numpy as np

from gyrotensegrity import diagnostics

from .attitude import Attitude
from .errors import PlanError

TABLE_POINTS = 401


def _string_between(model, a, b):
    """Index of the string joining scene nodes ``a`` and ``b`` (either direction)."""
    names = model.structure.node_names
    st = model.structure
    for k in range(model.alpha):
        pair = {names[st.string_start[k]], names[st.string_end[k]]}
        if pair == {a, b}:
            return k
    raise PlanError(f"scene {model.scene.name}: no string between {a} and {b}")


class DBarReduced:
    """Reduced D-bar model built from a full model.

    Parameters
    ----------
    model : gyrotensegrity.Model
        A D-bar scene: four bars of equal length around n1-n2-n3-n4 and strings n1-n3 (the
        actuated diagonal) and n2-n4 (the follower).

    Attributes
    ----------
    l : float, m
        Bar length.
    d_rest : float, m
        n1-n3 distance of the scene's initial (square) shape.
    i13, i24 : int
        Indices of the two strings in the model's input.
    d_table : ndarray, shape (TABLE_POINTS,), m
    inertia_table : ndarray, shape (TABLE_POINTS,), kg m^2
    wheel_table : ndarray, shape (TABLE_POINTS, n_w), kg m^2
    """

    def __init__(self, model):
        self.model = model
        self.attitude = Attitude(model)
        self.l = self._bar_length(model)
        self.i13 = _string_between(model, "n1", "n3")
        self.i24 = _string_between(model, "n2", "n4")
        self.d_rest = self.attitude.n13(model.structure.N0)
        self.d_table = np.linspace(1e-3 * self.l, (2.0 - 1e-3) * self.l, TABLE_POINTS)
        shapes = [self.shape(d) for d in self.d_table]
        axis = self.attitude.axis
        n_w = len(model.wheel_bars)
        self.inertia_table = np.array(
            [
                axis @ diagnostics.angular_momentum(model, N, np.cross(axis, N.T).T, np.zeros(n_w))
                for N in shapes
            ]
        )
        self.wheel_table = np.array(
            [
                [axis @ diagnostics.angular_momentum(model, N, 0.0 * N, e) for e in np.eye(n_w)]
                for N in shapes
            ]
        )

    @staticmethod
    def _bar_length(model):
        if model.beta != 4 or np.ptp(model.l) > 1e-9 * model.l[0]:
            raise PlanError(
                f"scene {model.scene.name}: the D-bar planner needs four bars of equal length"
            )
        return float(model.l[0])

    def follower_length(self, d):
        """n2-n4 distance (m) of the rhombus with n1-n3 distance ``d`` (m), any shape."""
        return np.sqrt(np.maximum(4.0 * self.l**2 - np.asarray(d) ** 2, 0.0))

    def shape(self, d):
        """Node positions (3, n), m, of the rhombus with n1-n3 distance ``d`` (m) in the
        reference frame (n1-n3 along the initial ``e_x``, n2-n4 along the tilt axis)."""
        R0 = self.attitude.frame(self.model.structure.N0)
        h = 0.5 * float(self.follower_length(d))
        local = {"n1": (-0.5 * d, 0.0), "n3": (0.5 * d, 0.0), "n2": (0.0, h), "n4": (0.0, -h)}
        centre = self.model.structure.N0[:, self.attitude.cols].mean(axis=1)
        names = self.model.structure.node_names
        cols = [centre + R0[:, 0] * local[n][0] + R0[:, 1] * local[n][1] for n in names]
        return np.column_stack(cols)

    def inertia(self, d):
        """Locked inertia about the tilt axis, kg m^2, same shape as ``d`` (m)."""
        return np.interp(d, self.d_table, self.inertia_table)

    def wheel_momentum(self, d, omega_w):
        """Wheel momentum along the tilt axis, kg m^2/s, for shapes ``d`` (k,) m and spins
        ``omega_w`` (n_w,) rad/s; shape (k,)."""
        h = self.wheel_table @ np.asarray(omega_w, float)
        return np.interp(d, self.d_table, h)

    def momentum(self, x, u):
        """Angular momentum (kg m^2/s) along the tilt axis of a full state ``x`` under ``u``."""
        m = self.model
        N, N_dot = m.nodes(x)
        H = diagnostics.angular_momentum(m, N, N_dot, m.wheel_speeds(x, u))
        return float(self.attitude.axis @ H)

    def tilt_rates(self, d, H_a, omega_w):
        """Tilt rate (rad/s) along a shape trajectory ``d`` (k,) m for the momentum ``H_a``
        (kg m^2/s) about the tilt axis and wheel spins ``omega_w`` (n_w,) rad/s; shape (k,)."""
        return (H_a - self.wheel_momentum(d, omega_w)) / self.inertia(d)

    def final_tilt(self, t, d, tilt0, H_a, omega_w):
        """Tilt (rad) at ``t[-1]`` from ``tilt0`` (rad) at ``t[0]``, shapes ``d`` (k,) m at
        times ``t`` (k,) s (trapezoidal quadrature of the tilt rate)."""
        w = self.tilt_rates(d, H_a, omega_w)
        return tilt0 + float(np.sum(0.5 * (w[1:] + w[:-1]) * np.diff(t)))


def rhombus_range(dbar: DBarReduced, limits, names):
    """Allowed n1-n3 rest lengths ``(lo, hi)``, m, of the D-bar ``dbar``: both diagonals at
    least ``limits.min_diagonal_m``, both rest lengths (strings ``names``: n1-n3, n2-n4) within
    their servo ranges, the rest shape inside (a maneuver starts and lands at rest)."""
    l2 = 4.0 * dbar.l**2
    lo13, hi13 = limits.range_of(names[0])
    lo24, hi24 = limits.range_of(names[1])
    short13, short24 = max(limits.min_diagonal_m, lo13), max(limits.min_diagonal_m, lo24)
    # the follower's rest length is sqrt(l2 - d^2): its range bounds d the other way
    lo = max(short13, np.sqrt(max(l2 - hi24**2, 0.0)))
    hi = min(hi13, np.sqrt(max(l2 - short24**2, 0.0)))
    if not lo < hi:
        raise PlanError(f"limits leave no n1-n3 length to command ({lo:.4g}..{hi:.4g} m)")
    if not lo <= dbar.d_rest <= hi:
        raise PlanError(
            f"limits leave the n1-n3 length {lo:.4g}..{hi:.4g} m, without the rest "
            f"shape {dbar.d_rest:.4g} m"
        )
    return lo, hi
