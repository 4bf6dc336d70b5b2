"""Model-based schedule: string rest lengths that turn the D-bar plane to a target tilt.

Decision variables: the n1-n3 rest length at a few *knots*, fixed absolute times
``linspace(t0, t_end, knots + 1)`` of one maneuver. The value at the start is the current
command (continuity for the servos) and the value at ``t_end`` is the square rest shape, so
the wheel momentum is back to its initial value and the plane *lands*: it stops turning (see
:mod:`.reduced`). The n2-n4 rest length follows the rhombus geometry. Between knots the n1-n3
rest length is linear; the schedule samples both strings every ``sample_dt_s`` or finer.

Cost (rad^2)::

    J = (tilt(t_end) - target)^2 + w_effort mean(((d - d_rest) / d_rest)^2)
                                 + w_smooth mean((diff(knots) / (v_max dt_knot))^2)

with ``tilt(t_end)`` predicted by the reduced model (:class:`.reduced.DBarReduced`).
Constraints (SLSQP, analytic gradients): both strings move at most ``v_max`` between any two
schedule samples; the n1-n3 rest length stays in ``[d_lo, d_hi]`` so that both diagonals stay
at least ``min_diagonal_m`` long (wheels of neighbouring bars do not touch) and both rest
lengths stay within the servos' length range. The strings stay taut by construction: the
follower's rest length equals the rhombus distance for the commanded n1-n3 rest length.

Re-planning (:mod:`.closed_loop`) keeps the knot times: the rest of the previous plan is then
exactly representable, so it is a feasible warm start and a re-plan can only improve on it.
"""

import time
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from .attitude import Attitude
from .errors import PlanError
from .reduced import DBarReduced, rhombus_range
from .schedule import Limits, Schedule


@dataclass(frozen=True)
class Weights:
    """Weights of the secondary cost terms (the tilt error term has weight 1, rad^-2)."""

    effort: float = 1e-4
    smooth: float = 1e-4


@dataclass(frozen=True)
class Plan:
    """Result of one optimisation.

    Attributes
    ----------
    schedule : Schedule
        Rest lengths of the two strings from ``t_start_s`` to ``t_end_s`` (absolute time, s).
    knot_t_s, knot_d_m : ndarray, shape (k,)
        Knot times (s) and n1-n3 rest lengths (m), including the fixed first and last knots.
    target_tilt_rad, predicted_tilt_rad : float
        Target and the reduced model's tilt at ``t_end_s``.
    success : bool
        The optimiser converged and the schedule is within the limits.
    message : str
    plan_time_s : float
        Wall time of the optimisation.
    n_eval : int
        Cost evaluations.
    """

    schedule: Schedule
    knot_t_s: np.ndarray
    knot_d_m: np.ndarray
    target_tilt_rad: float
    predicted_tilt_rad: float
    success: bool
    message: str
    plan_time_s: float
    n_eval: int


def _interp_matrix(t, knot_t):
    """Matrix A (len(t), len(knot_t)) with A @ values = np.interp(t, knot_t, values)."""
    A = np.zeros((len(t), len(knot_t)))
    j = np.clip(np.searchsorted(knot_t, t, side="right") - 1, 0, len(knot_t) - 2)
    w = (t - knot_t[j]) / (knot_t[j + 1] - knot_t[j])
    rows = np.arange(len(t))
    A[rows, j] = 1.0 - w
    A[rows, j + 1] = w
    return A


def _grid(knot_t, max_dt):
    """Knot times with every segment split into pieces of at most ``max_dt`` (s)."""
    parts = [knot_t[:1]]
    for a, b in zip(knot_t[:-1], knot_t[1:], strict=True):
        n = max(1, int(np.ceil((b - a) / max_dt - 1e-9)))
        parts.append(np.linspace(a, b, n + 1)[1:])
    return np.concatenate(parts)


class Planner:
    """Plans D-bar tilt maneuvers on the reduced model of a (nominal) full model.

    Parameters
    ----------
    model : gyrotensegrity.Model
        The planner's model (a D-bar scene).
    limits : Limits
    knots : int
        Knot intervals per maneuver (``knots - 1`` free values in the first plan).
    sample_dt_s : float, s
        Largest step of the schedule's time grid.
    quad_dt_s : float, s
        Largest step of the tilt quadrature.
    weights : Weights
    """

    def __init__(self, model, limits=None, knots=6, sample_dt_s=0.1, quad_dt_s=0.02, weights=None):
        if knots < 2:
            raise PlanError(f"knots must be at least 2, got {knots}")
        self.model = model
        self.dbar = DBarReduced(model)
        self.attitude: Attitude = self.dbar.attitude
        self.limits = limits or Limits()
        self.knots = int(knots)
        self.sample_dt_s, self.quad_dt_s = float(sample_dt_s), float(quad_dt_s)
        self.weights = weights or Weights()
        self.names = tuple(model.scene.strings[i].name for i in (self.dbar.i13, self.dbar.i24))
        self.d_lo, self.d_hi = rhombus_range(self.dbar, self.limits, self.names)
        dt = np.gradient(self.dbar.d_table)
        self._dinertia = np.gradient(self.dbar.inertia_table) / dt
        self._dwheel = np.gradient(self.dbar.wheel_table, axis=0) / dt[:, None]

    def knot_times(self, t0_s, t_end_s):
        """The maneuver's knot times (knots + 1,), s."""
        return np.linspace(t0_s, t_end_s, self.knots + 1)

    # -- optimisation ---------------------------------------------------------------------------
    def plan(
        self,
        target_tilt_rad,
        knot_t_s,
        t_start_s,
        tilt0_rad,
        momentum,
        omega_w,
        d_start_m,
        warm=None,
    ) -> Plan:
        """Optimise the knots after ``t_start_s``.

        Parameters
        ----------
        target_tilt_rad : float, rad
        knot_t_s : ndarray, shape (k,), s
            The maneuver's knot times (from :meth:`knot_times`); the last is the landing time.
        t_start_s : float, s
            Time the new schedule starts (the current time when re-planning).
        tilt0_rad : float, rad
            Tilt at ``t_start_s``.
        momentum : float, kg m^2/s
            Angular momentum about the tilt axis (:meth:`DBarReduced.momentum`).
        omega_w : ndarray, shape (n_w,), rad/s
            Wheel spins.
        d_start_m : float, m
            n1-n3 rest length commanded at ``t_start_s``.
        warm : Schedule, optional
            Previous schedule; its values at the free knots are the initial guess.
        """
        start = time.perf_counter()
        if not np.isfinite([target_tilt_rad, tilt0_rad, momentum, d_start_m]).all():
            raise PlanError("plan: target, tilt, momentum and start length must be finite")
        knot_t_s = np.asarray(knot_t_s, float)
        t_end = float(knot_t_s[-1])
        if not t_start_s < t_end:
            raise PlanError(f"plan: start {t_start_s:g} s is not before the end {t_end:g} s")
        free_t = knot_t_s[(knot_t_s > t_start_s + 1e-9) & (knot_t_s < t_end - 1e-9)]
        kt = np.concatenate([[t_start_s], free_t, [t_end]])
        problem = _Problem(self, kt, tilt0_rad, momentum, omega_w, d_start_m, target_tilt_rad)
        z0 = self._guess(kt, free_t, d_start_m, warm)
        z, ok, message = problem.solve(z0)
        kv = problem.values(z)
        schedule = problem.schedule(kv)
        problems = schedule.problems(self.limits)
        if problems:
            ok, message = False, f"{message}; limits: {'; '.join(problems)}"
        return Plan(
            schedule=schedule,
            knot_t_s=kt,
            knot_d_m=kv,
            target_tilt_rad=float(target_tilt_rad),
            predicted_tilt_rad=problem.final_tilt(kv),
            success=ok,
            message=message,
            plan_time_s=time.perf_counter() - start,
            n_eval=problem.n_eval,
        )

    def reach(self, knot_t_s, t_start_s, tilt0_rad, momentum, omega_w, d_start_m):
        """The lowest and highest tilt (rad) a plan can land at, within the limits.

        Parameters as :meth:`plan`. Each bound is an optimisation of the landing tilt alone
        under the same constraints (servo speed, length range, diagonals).
        """
        knot_t_s = np.asarray(knot_t_s, float)
        t_end = float(knot_t_s[-1])
        free_t = knot_t_s[(knot_t_s > t_start_s + 1e-9) & (knot_t_s < t_end - 1e-9)]
        kt = np.concatenate([[t_start_s], free_t, [t_end]])
        problem = _Problem(self, kt, tilt0_rad, momentum, omega_w, d_start_m, tilt0_rad)
        z0 = self._guess(kt, free_t, d_start_m, None)
        lo, hi = (problem.final_tilt(problem.values(problem.extreme(z0, s))) for s in (-1, 1))
        return lo, hi

    def _guess(self, kt, free_t, d_start, warm):
        if warm is not None:
            col = warm.names.index(self.names[0])
            z0 = np.interp(free_t, warm.t, warm.rest_length[:, col])
        else:
            z0 = np.interp(free_t, kt[[0, -1]], [d_start, self.dbar.d_rest])
        return np.clip(z0, self.d_lo, self.d_hi)

    # -- convenience ----------------------------------------------------------------------------
    def state_terms(self, x, t_s):
        """Tilt (rad), momentum about the tilt axis (kg m^2/s) and wheel spins (n_w,) rad/s
        of a full state ``x`` of the planner's model at ``t_s`` (s)."""
        m = self.model
        u = m.input_at(t_s)
        N, _ = m.nodes(x)
        return self.attitude.tilt(N), self.dbar.momentum(x, u), m.wheel_speeds(x, u)

    def plan_from_state(self, target_tilt_rad, x, t_s, knot_t_s, d_start_m=None, warm=None) -> Plan:
        """Plan from a full state ``x`` at ``t_s`` (s); the start length defaults to the rest
        shape (a maneuver from rest)."""
        tilt, momentum, omega_w = self.state_terms(x, t_s)
        d0 = self.dbar.d_rest if d_start_m is None else d_start_m
        return self.plan(target_tilt_rad, knot_t_s, t_s, tilt, momentum, omega_w, d0, warm)


class _Problem:
    """One optimisation: fixed first and last knots, free values in between."""

    def __init__(self, planner: Planner, kt, tilt0, momentum, omega_w, d_start, target):
        self.p, self.kt = planner, kt
        self.tilt0, self.H, self.target = float(tilt0), float(momentum), float(target)
        self.omega_w = np.asarray(omega_w, float)
        self.d_start, self.d_end = float(d_start), planner.dbar.d_rest
        tq = _grid(kt, planner.quad_dt_s)
        self.A_q = _interp_matrix(tq, kt)
        dtq = np.diff(tq)
        self.trap = np.concatenate([dtq, [0.0]]) * 0.5 + np.concatenate([[0.0], dtq]) * 0.5
        self.t_s = _grid(kt, planner.sample_dt_s)
        self.A_s = _interp_matrix(self.t_s, kt)
        self.dt_s = np.diff(self.t_s)
        self.dt_k = np.diff(kt)
        self.n_eval = 0

    def values(self, z):
        return np.concatenate([[self.d_start], z, [self.d_end]])

    def _rates(self, d):
        """Tilt rate (rad/s) and its derivative by d (rad/s/m) on the quadrature grid."""
        db = self.p.dbar
        inertia = np.interp(d, db.d_table, db.inertia_table)
        h = np.interp(d, db.d_table, db.wheel_table @ self.omega_w)
        dI = np.interp(d, db.d_table, self.p._dinertia)
        dh = np.interp(d, db.d_table, self.p._dwheel @ self.omega_w)
        w = (self.H - h) / inertia
        return w, (-dh - w * dI) / inertia

    def final_tilt(self, kv):
        w, _ = self._rates(self.A_q @ kv)
        return self.tilt0 + float(self.trap @ w)

    def cost(self, z):
        self.n_eval += 1
        p, kv = self.p, self.values(z)
        d = self.A_q @ kv
        w, dw = self._rates(d)
        e = self.tilt0 + self.trap @ w - self.target
        dr = (d - self.d_end) / self.d_end
        slope = np.diff(kv) / (p.limits.max_speed_m_s * self.dt_k)
        J = e**2 + p.weights.effort * np.mean(dr**2) + p.weights.smooth * np.mean(slope**2)
        g = 2.0 * e * ((self.trap * dw) @ self.A_q)
        g += p.weights.effort * 2.0 * (dr / self.d_end) @ self.A_q / len(d)
        D = np.diff(np.eye(len(kv)), axis=0) / (p.limits.max_speed_m_s * self.dt_k)[:, None]
        g += p.weights.smooth * 2.0 * (slope @ D) / len(slope)
        return J, g[1:-1]

    def speed_margins(self, z):
        """v_max dt - |step| of both strings between schedule samples, as 4 stacked arrays."""
        d = self.A_s @ self.values(z)
        f = self.p.dbar.follower_length(d)
        vdt = self.p.limits.max_speed_m_s * self.dt_s
        dd, df = np.diff(d), np.diff(f)
        return np.concatenate([vdt - dd, vdt + dd, vdt - df, vdt + df])

    def speed_jacobian(self, z):
        d = self.A_s @ self.values(z)
        fp = -d / np.maximum(self.p.dbar.follower_length(d), 1e-12)  # d follower / d d
        Jd = np.diff(self.A_s, axis=0)
        Jf = np.diff(fp[:, None] * self.A_s, axis=0)
        return np.vstack([-Jd, Jd, -Jf, Jf])[:, 1:-1]

    def landing(self, z, sign):
        """``sign`` times the landing tilt (rad) and its gradient by the free knots."""
        kv = self.values(z)
        _, dw = self._rates(self.A_q @ kv)
        return sign * self.final_tilt(kv), sign * ((self.trap * dw) @ self.A_q)[1:-1]

    def extreme(self, z0, sign):
        """Free knots of the lowest (``sign`` -1) or highest (+1) landing tilt."""
        if z0.size == 0:
            return z0
        return self._minimize(lambda z: self.landing(z, -sign), z0).x.clip(self.p.d_lo, self.p.d_hi)

    def _minimize(self, cost, z0):
        return optimize.minimize(
            cost,
            z0,
            jac=True,
            method="SLSQP",
            bounds=[(self.p.d_lo, self.p.d_hi)] * z0.size,
            constraints=[{"type": "ineq", "fun": self.speed_margins, "jac": self.speed_jacobian}],
            options={"maxiter": 200, "ftol": 1e-14},
        )

    def solve(self, z0):
        if z0.size == 0:
            return z0, True, "no free knots left: the schedule runs to its end"
        res = self._minimize(self.cost, z0)
        return np.clip(res.x, self.p.d_lo, self.p.d_hi), bool(res.success), str(res.message)

    def schedule(self, kv):
        # Sampling between knots on a bound (and the follower of a bound) may round one ulp
        # past it: the samples are clipped so that no command leaves the limits.
        d = np.clip(self.A_s @ kv, self.p.d_lo, self.p.d_hi)
        f = np.clip(self.p.dbar.follower_length(d), *self.p.limits.range_of(self.p.names[1]))
        return Schedule(self.p.names, self.t_s, np.column_stack([d, f]), "plan")


def plan(model, target_tilt_rad, duration_s, limits=None, **options) -> Plan:
    """Plan a tilt maneuver of ``duration_s`` (s) from the model's initial state (at rest).

    Parameters
    ----------
    model : gyrotensegrity.Model
        The planner's (nominal) model of a D-bar scene.
    target_tilt_rad : float, rad
        Tilt to land at, at ``duration_s``.
    duration_s : float, s
    limits : Limits, optional
    **options
        Passed to :class:`Planner` (``knots``, ``sample_dt_s``, ``quad_dt_s``, ``weights``).
    """
    if not duration_s > 0.0:
        raise PlanError(f"duration_s must be positive, got {duration_s}")
    planner = Planner(model, limits, **options)
    kt = planner.knot_times(0.0, float(duration_s))
    return planner.plan_from_state(target_tilt_rad, model.initial_state(), 0.0, kt)
