"""Three-axis attitude plans: rest-length and wheel-speed trajectories that turn any free scene
to a target attitude and land it there (no rotation left), within the servo and wheel limits.

Direct single shooting on the reduced model (:class:`.shape_attitude.AttitudeModel`). The
inputs ``u = [r_dot | omega_w_dot]`` are constant on ``K`` intervals between knots fixed in
absolute time (as :class:`.planner.Planner`'s, so a re-plan's warm start is the rest of the
previous plan); each interval is ``substeps`` RK4 steps of the model. The decision vector is the
active inputs of every interval not yet begun, scaled by their limits (``--strings-only``
holds the wheels' spins, ``--wheels-only`` the rest lengths).

Cost (rad^2)::

    J = 4 |vec(q_target^-1 q_K)|^2 / |q_K|^2 + w_servo mean((r_dot / v_max)^2)
                                           + w_wheel mean((omega_w_dot / a_max)^2)

the first term is ``(2 sin(theta / 2))^2`` of the geodesic landing error ``theta``. Constraints
(SLSQP): input boxes (servo speed, wheel acceleration); at every knot the coordinates within the
shape table's box, every scheduled rest length within its servo range and changing at most at
the servo speed, the wheels within the speed limit, the strings taut at the quasi-static shape;
the landing: body rate at the end (inputs stopped) at most ``landing_rate_rad_s``, the rest
lengths back at the scene's (when the strings move). Gradients of all of them by complex step
through the integrator: one batch of complex copies, one per decision variable, integrated at
once, so that a gradient costs one batched simulation, not one simulation per variable.

An unreachable target is refused with the reachable range of the rotation about its own axis
(:meth:`AttitudePlanner.reach`, the same problem with the angle about that axis as the cost).
"""

import time
from dataclasses import dataclass

import numpy as np
from scipy import optimize
from scipy.spatial.transform import Rotation

from gyrotensegrity.attitude import angle_between

from .attitude_model import quaternion_product
from .deadline import NONE
from .errors import PlanError
from .schedule import Schedule
from .shape import RhombusShape
from .shape_attitude import AttitudeModel
from .target_shape import landing_coordinates

MODES = ("both", "strings", "wheels")
LANDING_RATE_RAD_S = 5e-4
"""Largest body rate a plan leaves at its landing (0.03 deg/s: it drifts less than the refusal's
0.005 rad in 10 s after it)."""
MAX_ITER = 100
"""SLSQP iterations of one plan by default (a reachable target converges in tens where the
wheels' reactions reach the body; an unreachable one stops here and is refused). Wheels that act
only gyroscopically (:mod:`.wheel_reaction`, ``lost``) turn the body at second order in the
inputs, and such plans need a few hundred."""
MAX_ITER_GYROSCOPIC = 400
"""SLSQP iterations of one plan by default when a planned wheel's reaction is lost."""
FEASIBLE = 1e-6
"""Largest violation of a constraint (its own unit: m, rad/s, rad^2/s^2) of a plan that
counts as within the limits, for the reach's bounds."""
STEP = 1e-30
"""Complex step: far below round-off of any value here, so derivatives are exact to it."""


@dataclass(frozen=True)
class AttitudeWeights:
    """Weights of the effort terms (the landing term has weight 1, rad^-2)."""

    servo: float = 1e-4
    wheel: float = 1e-4


@dataclass(frozen=True)
class AttitudePlan:
    """Result of one optimisation.

    Attributes
    ----------
    schedule : Schedule
        Rest lengths and (unless strings only) wheel speeds from the start to the landing.
    knot_t_s : ndarray, shape (K + 1,), s
    states : ndarray, shape (K + 1, n_x)
        The reduced model's state at the knots.
    inputs : ndarray, shape (K, n_u)
        ``[r_dot | omega_w_dot]`` on each interval.
    target_q, predicted_q : ndarray, shape (4,)
    landing_error_rad : float
        Geodesic angle between the two.
    landing_rate_rad_s : float
        Body rate left at the landing.
    success : bool
    message : str
    plan_time_s : float
    n_eval : int
    """

    schedule: Schedule
    knot_t_s: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    target_q: np.ndarray
    predicted_q: np.ndarray
    landing_error_rad: float
    landing_rate_rad_s: float
    success: bool
    message: str
    plan_time_s: float
    n_eval: int


def conjugate(q):
    """Conjugates (..., 4) of quaternions (..., 4), w first: the inverse rotations of unit
    ones (complex-step safe)."""
    return np.concatenate([q[..., :1], -q[..., 1:]], axis=-1)


class AttitudePlanner:
    """Plans attitude maneuvers of an :class:`AttitudeModel`.

    Parameters
    ----------
    model : AttitudeModel
    knots : int
        Intervals per maneuver.
    substeps : int
        RK4 steps per interval.
    mode : str
        One of :data:`MODES`: both actuators, strings only, wheels only.
    landing_rate_rad_s : float, rad/s
        Largest body rate left at the landing.
    sample_dt_s : float, s
        Largest step of the schedule's time grid.
    weights : AttitudeWeights
    max_iter : int, optional
        SLSQP iterations of one plan (default :data:`MAX_ITER`, or
        :data:`MAX_ITER_GYROSCOPIC` when a planned wheel's reaction is lost).
    """

    def __init__(
        self,
        model: AttitudeModel,
        knots=8,
        substeps=2,
        mode="both",
        landing_rate_rad_s=LANDING_RATE_RAD_S,
        sample_dt_s=0.05,
        weights=None,
        max_iter=None,
    ):
        if mode not in MODES:
            raise PlanError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
        if knots < 1 or substeps < 1:
            raise PlanError(f"knots and substeps must be at least 1, got {knots}, {substeps}")
        self.model, self.knots, self.substeps, self.mode = model, int(knots), int(substeps), mode
        self.landing_rate_rad_s, self.sample_dt_s = float(landing_rate_rad_s), float(sample_dt_s)
        self.weights = weights or AttitudeWeights()
        lim = model.limits
        n_x, n_u = model.size
        scale = np.concatenate(
            [np.full(model.a, lim.max_speed_m_s), np.full(model.n_w, lim.max_wheel_accel_rad_s2)]
        )
        active = np.ones(n_u, bool)
        active[: model.a] = mode != "wheels" and model.a > 0
        active[model.a :] = (mode != "strings") & model.steerable  # `own` wheels held
        if not active.any():
            raise PlanError(f"mode {mode}: the scene has nothing to move (no strings or wheels)")
        self.active, self.scale = np.flatnonzero(active), scale
        self.moves_lost_wheels = bool((active[model.a :] & model.lost).any())
        """Whether a planned wheel's reaction is lost (:mod:`.wheel_reaction`): its spin-ups
        change the total momentum and turn the body only gyroscopically."""
        if max_iter is None:
            max_iter = MAX_ITER_GYROSCOPIC if self.moves_lost_wheels else MAX_ITER
        self.max_iter = int(max_iter)
        self.n_x, self.n_u = n_x, n_u
        self._taut = not isinstance(model.shape, RhombusShape)  # the rhombus: no tension

    @property
    def limits(self):
        """The servo and wheel limits the plans keep (the model's)."""
        return self.model.limits

    def knot_times(self, t0_s, t_end_s):
        """The maneuver's knot times (knots + 1,), s."""
        return np.linspace(t0_s, t_end_s, self.knots + 1)

    # -- the trajectory ---------------------------------------------------------------------------
    def inputs(self, z, n_free):
        """Inputs (..., n_free, n_u) of scaled decision vectors ``z`` (..., n_free * n_active)."""
        u = np.zeros(z.shape[:-1] + (n_free, self.n_u), dtype=z.dtype)
        u[..., self.active] = z.reshape(z.shape[:-1] + (n_free, len(self.active)))
        return u * self.scale

    def simulate(self, x0, H0, u, dt, deadline=NONE):
        """States (..., k + 1, n_x) at the knots from ``x0`` under inputs ``u`` (..., k, n_u)
        held on intervals ``dt`` (k,) s (RK4, ``substeps`` per interval); each step checks
        ``deadline`` (:class:`.deadline.Deadline`) first."""
        f = self.model.rhs
        x = np.broadcast_to(x0, u.shape[:-2] + (self.n_x,)).astype(u.dtype)
        out = [x]
        deadline.begin()
        for k, span in enumerate(dt):
            h, uk = span / self.substeps, u[..., k, :]
            for _ in range(self.substeps):
                deadline.check()
                k1 = f(0.0, x, uk, H0)
                k2 = f(0.0, x + 0.5 * h * k1, uk, H0)
                k3 = f(0.0, x + 0.5 * h * k2, uk, H0)
                k4 = f(0.0, x + h * k3, uk, H0)
                x = x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            out.append(x)
        return np.stack(out, axis=-2)

    def landing_rate(self, x_end, H0):
        """Body rate (..., 3) rad/s left at states ``x_end`` once the inputs stop."""
        return self.model.body_rate(x_end, np.zeros(x_end.shape[:-1] + (self.n_u,)), H0)

    # -- planning ---------------------------------------------------------------------------------
    def plan(self, target_q, knot_t_s, t_start_s, x0, H0, warm=None, r_end=None) -> AttitudePlan:
        """Optimise the inputs of the intervals after ``t_start_s``.

        Parameters
        ----------
        target_q : ndarray, shape (4,)
            Target attitude (quaternion, w first) relative to the start frame.
        knot_t_s : ndarray, shape (K + 1,), s
            The maneuver's knot times (:meth:`knot_times`).
        t_start_s : float, s
        x0 : ndarray, shape (n_x,)
            The reduced model's state at ``t_start_s`` (:meth:`AttitudeModel.start`).
        H0 : ndarray, shape (3,), kg m^2/s
        warm : AttitudePlan, optional
            A previous plan on the same knots: its inputs are the initial guess.
        r_end : ndarray, shape (a,), m, optional
            Coordinates to land at (:func:`.target_shape.target_coordinates`; default the
            scene's rest lengths).
        """
        start = time.perf_counter()
        problem = self._problem(target_q, knot_t_s, t_start_s, x0, H0, r_end)
        z0 = problem.guess(warm)
        z, ok, message = problem.solve(z0, problem.cost)
        return problem.result(z, ok, message, time.perf_counter() - start)

    def reach(self, axis, knot_t_s, t_start_s, x0, H0, r_end=None):
        """The smallest and largest rotation (rad) about the unit ``axis`` (3,), start frame,
        that a plan can land at within the limits: each the furthest of the iterates of an
        optimisation of that angle that keep every limit (NaN: none does; from rest, holding
        still does, so the range holds 0)."""
        identity = np.array([1.0, 0.0, 0.0, 0.0])
        problem = self._problem(identity, knot_t_s, t_start_s, x0, H0, r_end)
        problem.axis = np.asarray(axis, float) / np.linalg.norm(axis)
        bounds = []
        for sign in (-1.0, 1.0):
            best = [np.nan, None]

            def keep(z, sign=sign, best=best):
                if problem.feasible(z) and not sign * problem.twist_value(z) <= sign * best[0]:
                    best[:] = [problem.twist_value(z), z.copy()]

            z0 = problem.guess(None)
            keep(z0)
            keep(problem.solve(z0, lambda z, s=sign: problem.twist(z, s), keep)[0])
            bounds.append(best[0])
        return tuple(bounds)

    def _problem(self, target_q, knot_t_s, t_start_s, x0, H0, r_end=None):
        knot_t_s = np.asarray(knot_t_s, float)
        x0, H0, target_q = (np.asarray(v, float) for v in (x0, H0, target_q))
        if not (np.isfinite(x0).all() and np.isfinite(H0).all() and np.isfinite(target_q).all()):
            raise PlanError("plan: target, state and momentum must be finite")
        if x0.shape != (self.n_x,):
            raise PlanError(f"plan: the state has {x0.size} entries, the model {self.n_x}")
        t_end = float(knot_t_s[-1])
        if not t_start_s < t_end:
            raise PlanError(f"plan: start {t_start_s:g} s is not before the end {t_end:g} s")
        inner = knot_t_s[(knot_t_s > t_start_s + 1e-9) & (knot_t_s < t_end - 1e-9)]
        kt = np.concatenate([[t_start_s], inner, [t_end]])
        problem = _Problem(self, kt, x0, H0, target_q / np.linalg.norm(target_q))
        if r_end is not None:
            problem.r_end = np.asarray(r_end, float)
        return problem


class _Problem:
    """One optimisation: the intervals of ``kt`` from the state ``x0``."""

    def __init__(self, planner: AttitudePlanner, kt, x0, H0, target_q):
        self.p, self.kt, self.x0, self.H0, self.target = planner, kt, x0, H0, target_q
        self.dt = np.diff(kt)
        self.n_free = len(self.dt)
        self.n_z = self.n_free * len(planner.active)
        self.n_eval, self.axis = 0, None
        self._cache = self._kept = (None, None)
        self.r_end = planner.model.shape.rest
        self.deadline = NONE

    def guess(self, warm):
        if warm is None:
            return np.zeros(self.n_z)
        mid = 0.5 * (self.kt[:-1] + self.kt[1:])
        k = np.clip(np.searchsorted(warm.knot_t_s, mid, side="right") - 1, 0, len(warm.inputs) - 1)
        u = warm.inputs[k][:, self.p.active] / self.p.scale[self.p.active]
        return np.clip(u.ravel(), -1.0, 1.0)

    def trajectory(self, z):
        """States (n_z + 1, K + 1, n_x): the nominal (real) and one complex copy per variable;
        raises :class:`.errors.PastDeadline` past :attr:`deadline`."""
        held = self._held(z)
        if held is not None:
            return held
        self.n_eval += 1
        Z = z + 1j * STEP * np.eye(self.n_z)
        Z = np.vstack([z[None].astype(complex), Z])
        X = self.p.simulate(self.x0, self.H0, self.p.inputs(Z, self.n_free), self.dt, self.deadline)
        self._cache = (z.copy(), (X, Z))
        return X, Z

    def _held(self, z):
        """The trajectory of ``z`` if it is the last one or the kept one, else None."""
        for cached, XZ in (self._cache, self._kept):
            if cached is not None and np.array_equal(cached, z):
                return XZ
        return None

    def _nominal(self, z):
        """States (K + 1, n_x) of ``z`` alone: held, or simulated without the complex copies
        (a re-plan cut before its first trajectory)."""
        held = self._held(z)
        if held is not None:
            return np.real(held[0][0])
        return self.p.simulate(self.x0, self.H0, self.p.inputs(z[None], self.n_free), self.dt)[0]

    def keep(self, z) -> None:
        """Hold the trajectory of ``z`` (computed before) apart from the last one: the plan a
        bounded re-plan returns, whatever it tried after it."""
        self._kept = (z.copy(), self.trajectory(z))

    def _value_grad(self, values):
        """``(value, gradient)`` of batched outputs (n_z + 1, ...): the first copy's real part,
        the others' imaginary parts over the step."""
        return np.real(values[0]), np.moveaxis(np.imag(values[1:]) / STEP, 0, -1)

    def _landing(self, X):
        q = X[..., -1, :4]
        e = quaternion_product(np.moveaxis(conjugate(self.target), -1, 0), np.moveaxis(q, -1, 0))
        return 4.0 * np.sum(e[1:] ** 2, axis=0) / np.sum(q * q, axis=-1)

    def _effort(self, Z):
        u = self.p.inputs(Z, self.n_free) / self.p.scale
        w = self.dt / self.dt.sum()
        a, weights = self.p.model.a, self.p.weights
        servo = np.sum(np.sum(u[..., :a] ** 2, axis=-1) * w, axis=-1)
        wheel = np.sum(np.sum(u[..., a:] ** 2, axis=-1) * w, axis=-1)
        return weights.servo * servo + weights.wheel * wheel

    def cost(self, z):
        X, Z = self.trajectory(z)
        return self._value_grad(self._landing(X) + self._effort(Z))

    def twist(self, z, sign):
        """``-sign`` times ``sin(phi / 2)`` of the landing rotation ``phi`` about ``axis`` (its
        quaternion's component along it), and its gradient: smooth and bounded, so that the
        extremes stop at a half turn instead of running off where ``phi`` wraps."""
        X, Z = self.trajectory(z)
        q = X[..., -1, :4]
        along = (q[..., 1:] @ self.axis) / np.sqrt(np.sum(q * q, axis=-1))
        return self._value_grad(-sign * along + self._effort(Z))

    def twist_value(self, z):
        """The landing rotation about ``axis``, rad, in [-pi, pi]."""
        X, _ = self.trajectory(z)
        q = np.real(X[0, -1, :4])
        q = -q if q[0] < 0.0 else q  # the same rotation, its angle within a half turn
        return float(2.0 * np.arctan2(q[1:] @ self.axis, q[0]))

    def inequalities(self, z):
        """Stacked margins (>= 0) at the knots and the landing, batched."""
        X, _ = self.trajectory(z)
        w = self.p.landing_rate(X[:, -1], self.H0)
        landing = (self.p.landing_rate_rad_s**2 - np.sum(w * w, axis=-1))[:, None]
        return self._value_grad(np.concatenate([self._margins(X), landing], axis=1))

    def margins(self, z):
        """The limits' margins (>= 0) at the knots, batched (the landing's left out)."""
        return self._value_grad(self._margins(self.trajectory(z)[0]))

    def _margins(self, X):
        p, model = self.p, self.p.model
        lim = model.limits
        _, r, omega = model.split(X[:, 1:])
        table = model.table
        parts = [r - table.lo, table.hi - r]
        rest = model.shape.rest_lengths(X[:, :, 4 : 4 + model.a])
        ranges = np.array([lim.range_of(n) for n in model.names]).reshape(-1, 2)
        parts += [rest[:, 1:] - ranges[:, 0], ranges[:, 1] - rest[:, 1:]]
        rates = np.diff(rest, axis=1) / self.dt[:, None]  # each interval's mean rate
        parts += [lim.max_speed_m_s - rates, lim.max_speed_m_s + rates]
        parts += [lim.max_wheel_speed_rad_s - omega, lim.max_wheel_speed_rad_s + omega]
        if p._taut:
            parts.append(self._slack_margin(r))
        return np.concatenate([v.reshape(len(X), -1) for v in parts], axis=1)

    def _slack_margin(self, r):
        """Each string's length minus its rest length (m) at the quasi-static shapes ``r``."""
        model = self.p.model
        _, _, _, L = model.terms(r)
        rest = np.broadcast_to(model.shape.rest_all, L.shape).astype(np.result_type(L, r))
        rest[..., model.shape.idx] = r
        return L - rest

    def equalities(self, z):
        """The coordinates at the landing ``r_end`` (m; the scene's rest lengths unless a
        target shape), batched."""
        X, _ = self.trajectory(z)
        return self._value_grad(X[:, -1, 4 : 4 + self.p.model.a] - self.r_end)

    def feasible(self, z):
        """Whether ``z`` keeps every constraint (to :data:`FEASIBLE`)."""
        worst = -np.min(self.inequalities(z)[0], initial=0.0)
        if self.p.mode != "wheels" and self.p.model.a:
            worst = max(worst, float(np.max(np.abs(self.equalities(z)[0]))))
        return worst <= FEASIBLE

    def solve(self, z0, cost, callback=None):
        if self.n_z == 0:
            return z0, True, "no interval left: the schedule runs to its end"
        constraints = [
            {"type": "ineq", "fun": lambda z: self.inequalities(z)[0],
             "jac": lambda z: self.inequalities(z)[1]},
        ]  # fmt: skip
        if self.p.mode != "wheels" and self.p.model.a:
            constraints.append(
                {"type": "eq", "fun": lambda z: self.equalities(z)[0],
                 "jac": lambda z: self.equalities(z)[1]}
            )  # fmt: skip
        res = optimize.minimize(
            cost,
            z0,
            jac=True,
            method="SLSQP",
            bounds=[(-1.0, 1.0)] * self.n_z,
            constraints=constraints,
            options={"maxiter": self.p.max_iter, "ftol": 1e-12},
            callback=callback,
        )
        return np.clip(res.x, -1.0, 1.0), bool(res.success), str(res.message)

    def result(self, z, ok, message, plan_time_s) -> AttitudePlan:
        states = self._nominal(z)
        inputs = self.p.inputs(z, self.n_free)
        q = states[-1, :4] / np.linalg.norm(states[-1, :4])
        rate = float(np.linalg.norm(self.p.landing_rate(states[-1], self.H0)))
        schedule = self.schedule(states)
        problems = schedule.problems(self.p.model.limits)
        if problems:
            ok, message = False, f"{message}; limits: {'; '.join(problems)}"
        return AttitudePlan(
            schedule=schedule,
            knot_t_s=self.kt,
            states=states,
            inputs=inputs,
            target_q=self.target,
            predicted_q=q,
            landing_error_rad=float(angle_between(self.target, q)),
            landing_rate_rad_s=rate,
            success=ok,
            message=message,
            plan_time_s=plan_time_s,
            n_eval=self.n_eval,
        )

    def schedule(self, states) -> Schedule:
        """Rest lengths and wheel speeds sampled at most ``sample_dt_s`` apart (coordinates
        and spins are linear between knots: the inputs are constant there)."""
        model, p = self.p.model, self.p
        pieces = [self.kt[:1]]
        for a, b in zip(self.kt[:-1], self.kt[1:], strict=True):
            n = max(1, int(np.ceil((b - a) / p.sample_dt_s - 1e-9)))
            pieces.append(np.linspace(a, b, n + 1)[1:])
        t = np.concatenate(pieces)
        x = np.column_stack([np.interp(t, self.kt, col) for col in states.T])
        _, r, omega = model.split(x)
        names = model.names if p.mode != "wheels" else ()
        rest = model.shape.rest_lengths(r) if names else np.zeros((t.size, 0))
        lim = model.limits
        ranges = np.array([lim.range_of(n) for n in names]).reshape(-1, 2)
        rest = np.clip(rest, ranges[:, 0], ranges[:, 1])  # a knot on a bound, one ulp past
        wheels = model.wheels if p.mode != "strings" else ()
        speeds = omega if wheels else np.zeros((t.size, 0))
        return Schedule(names, t, rest, "attitude", wheels, speeds)


def target_quaternion(rpy_rad):
    """Quaternion (w first) of roll, pitch, yaw (rad) in the frame's intrinsic Z-Y'-X''
    convention (:mod:`gyrotensegrity.attitude`)."""
    roll, pitch, yaw = (float(v) for v in rpy_rad)
    return Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_quat(scalar_first=True)


def plan_attitude(
    model,
    target_rpy_rad,
    duration_s,
    limits=None,
    strings=None,
    mode="both",
    tolerance_rad=0.005,
    target_rest=None,
    **options,
) -> AttitudePlan:
    """Plan a maneuver of ``duration_s`` (s) from the model's initial state to the attitude
    ``target_rpy_rad`` (roll, pitch, yaw, rad, the scene's body frame), refusing it when the
    best plan lands more than ``tolerance_rad`` off.

    Parameters
    ----------
    model : gyrotensegrity.Model
        A free scene with an ``[attitude]`` frame.
    target_rpy_rad : sequence of 3 float, rad
    duration_s : float, s
    limits : Limits, optional
    strings : sequence of str, optional
        Actuated strings (default: those the scene schedules).
    mode : str
        ``both``, ``strings`` (wheels held) or ``wheels`` (rest lengths held).
    tolerance_rad : float, rad
    target_rest : dict, optional
        ``{string: rest length (m)}`` to land at (:mod:`.target_shape`; strings not named land
        at the scene's rest lengths).
    **options
        Passed to :class:`AttitudePlanner` (``knots``, ``substeps``, ``landing_rate_rad_s``,
        ``sample_dt_s``, ``weights``, ``max_iter``).

    Raises
    ------
    PlanError
        Bad request, or the target is out of reach (the message gives the reachable rotation
        about the target's axis).
    """
    if not (np.isfinite(duration_s) and duration_s > 0.0):
        raise PlanError(f"duration must be positive, got {duration_s} s")
    target = np.asarray(target_rpy_rad, float)
    if target.shape != (3,) or not np.isfinite(target).all():
        raise PlanError(f"target attitude must be three finite angles, got {target_rpy_rad}")
    reduced = AttitudeModel(model, strings, limits)
    planner = AttitudePlanner(reduced, mode=mode, **options)
    r_end = landing_coordinates(planner, target_rest)
    kt = planner.knot_times(0.0, float(duration_s))
    x0, H0 = reduced.start(model.initial_state())
    q_target = target_quaternion(target)
    plan = planner.plan(q_target, kt, 0.0, x0, H0, r_end=r_end)
    if not reachable(planner, plan, tolerance_rad):
        why = refusal(planner, plan, kt, x0, H0, target, tolerance_rad, duration_s, r_end)
        raise PlanError(why)
    return plan


def reachable(planner, plan, tolerance_rad) -> bool:
    """Whether the first plan lands within ``tolerance_rad`` of its target, nearly still."""
    return (
        plan.landing_error_rad <= tolerance_rad
        and plan.landing_rate_rad_s <= 2 * planner.landing_rate_rad_s
    )


def refusal(planner, plan, kt, x0, H0, target_rpy, tolerance_rad, duration_s, r_end=None) -> str:
    """Why ``plan`` is refused: the reachable rotation about the target's axis (landing at the
    coordinates ``r_end``, or the start's)."""
    rotvec = Rotation.from_quat(plan.target_q, scalar_first=True).as_rotvec()
    angle = float(np.linalg.norm(rotvec))
    axis = rotvec / angle if angle > 0.0 else np.array([0.0, 0.0, 1.0])
    lo, hi = planner.reach(axis, kt, 0.0, x0, H0, r_end)
    deg = np.degrees
    within = (
        f"lands turned between {deg(lo):+.2f} and {deg(hi):+.2f} deg about that axis (about "
        "the others as it may)"
        if np.isfinite([lo, hi]).all()
        else "finds no landing (body rate at most "
        f"{deg(planner.landing_rate_rad_s):.2f} deg/s) that turns further about that axis"
    )
    return (
        f"target attitude (roll, pitch, yaw) {', '.join(f'{v:+.2f}' for v in deg(target_rpy))} "
        f"deg is out of reach in {duration_s:g} s ({planner.mode}): a turn of {deg(angle):.2f} "
        f"deg about the axis ({', '.join(f'{v:+.3f}' for v in axis)}); within the limits it "
        f"{within} (the best plan "
        f"lands {deg(plan.landing_error_rad):.2f} deg off, more than {deg(tolerance_rad):.2f} "
        f"deg, turning {deg(plan.landing_rate_rad_s):.2f} deg/s); choose a target in that "
        "range or another duration"
    )
