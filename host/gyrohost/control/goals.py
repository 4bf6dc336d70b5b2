"""What a receding-horizon re-planner steers toward: the D-bar's tilt or a three-axis attitude.

:class:`.closed_loop.Replanner` owns the period, the knots and the schedule in force; a goal
owns its planner and turns an estimate (a full state of the planner's model, as the EKF gives
it) into a plan:

- :class:`TiltGoal`: the one-axis tilt planner (:class:`.planner.Planner`), re-planned to
  convergence from the measured tilt and momentum, with the wheel-gain fit
  (:class:`.adapt.WheelGainFit`) when adapting.
- :class:`AttitudeGoal`: the three-axis planner (:class:`.attitude_planner.AttitudePlanner`);
  the first plan runs to convergence, every re-plan is a real-time iteration of bounded work
  (:class:`.realtime_iteration.RealTimeIteration`) from the plan in force.

Both re-plan from the rest lengths (and wheel speeds) the schedule in force commands at the
re-plan's time, so that the new schedule starts where the servos (and the wheel board) are
being sent: the splice has no jump.
"""

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from gyrotensegrity.attitude import angle_between

from .adapt import MomentumGainFit, WheelGainFit
from .attitude_planner import AttitudePlanner, reachable, refusal, target_quaternion
from .planner import Planner
from .realtime_iteration import RealTimeIteration
from .target_shape import landing_coordinates


@dataclass
class ReplanRecord:
    """One re-plan: time (s), measured tilt (rad), the new plan's prediction (rad), plan wall
    time (s), whether it was accepted, the optimiser's message, the wheel-momentum gain the
    plan used (1 without adaptation), and the estimate's and the plan's landing distance from
    the target (rad: the tilt's difference or the geodesic angle; the tilt fields are NaN for
    an attitude goal, which measures the distance only)."""

    t_s: float
    tilt_rad: float
    predicted_tilt_rad: float
    plan_time_s: float
    accepted: bool
    message: str
    kappa: float = 1.0
    error_rad: float = float("nan")
    predicted_error_rad: float = float("nan")


class TiltGoal:
    """The D-bar's tilt: ``target`` rad about its n2-n4 axis (docs/schedule.md)."""

    def __init__(self, planner: Planner, target: float):
        self.planner, self.target = planner, float(target)

    def first(self, t_s, x, knot_t):
        return self.planner.plan_from_state(self.target, x, t_s, knot_t)

    def miss(self, plan) -> float:
        """How far (rad) the plan lands from the target."""
        return abs(plan.predicted_tilt_rad - self.target)

    def gain_fit(self, t_s, x):
        _, momentum, omega_w = self.planner.state_terms(x, t_s)
        return WheelGainFit(self.planner.dbar, momentum, omega_w)

    def observe(self, fit, x) -> None:
        N, N_dot = self.planner.model.nodes(x)
        att = self.planner.attitude
        fit.add(att.n13(N), att.tilt_rate(N, N_dot))

    def again(self, t_s, x, knot_t, schedule, fitted):
        """``(plan, kappa)`` from the estimate ``x`` at ``t_s``, warm from ``schedule``."""
        col = schedule.names.index(self.planner.names[0])
        d_now = float(schedule(t_s)[col])
        tilt, momentum, omega_w = self.planner.state_terms(x, t_s)
        kappa = 1.0
        if fitted is not None:
            momentum, kappa = fitted
        plan = self.planner.plan(
            self.target, knot_t, t_s, tilt, momentum, kappa * omega_w, d_now, warm=schedule
        )
        return plan, kappa

    def record(self, t_s, x, plan, accepted, kappa) -> ReplanRecord:
        tilt = self.planner.attitude.tilt(self.planner.model.nodes(x)[0])
        return ReplanRecord(
            t_s, tilt, plan.predicted_tilt_rad, plan.plan_time_s, accepted, plan.message, kappa,
            abs(tilt - self.target), self.miss(plan),
        )  # fmt: skip

    def refusal(self, plan, x0, knot_t, duration_s, tolerance_rad) -> str | None:
        """None if the first plan lands within ``tolerance_rad``, else why it is refused: the
        tilts reachable in ``duration_s``."""
        if self.miss(plan) <= tolerance_rad:
            return None
        tilt, momentum, omega_w = self.planner.state_terms(x0, 0.0)
        lo, hi = self.planner.reach(knot_t, 0.0, tilt, momentum, omega_w, self.planner.dbar.d_rest)
        return (
            f"target tilt {self.target:+.4f} rad is out of reach in {duration_s:g} s: within "
            f"the servo limits the plane lands between {lo:+.4f} and {hi:+.4f} rad (the best "
            f"plan lands at {plan.predicted_tilt_rad:+.4f} rad, {self.miss(plan):.4f} rad "
            f"off, more than {tolerance_rad:g} rad); choose a target in that range or another "
            "duration"
        )

    def summary(self, plan) -> dict:
        return {"predicted_tilt_rad": plan.predicted_tilt_rad}


FIRST_ROUNDS = 4
"""Iteration budgets (``AttitudePlanner.max_iter`` each) the first attitude plan may take."""
ITERATION_LIMIT = "Iteration limit"
"""How SLSQP's message says it stopped on its budget."""


class AttitudeGoal:
    """A three-axis attitude: ``target`` roll, pitch, yaw (rad) of the scene's body frame,
    landing at the rest lengths ``target_rest`` (``{string: m}``, :mod:`.target_shape`; the
    scene's where not given); a re-plan begins its steps within half the re-planning period
    ``period_s`` (the other half is the run loop's and the estimator's on a two-core machine)
    and is cut at the period (:class:`.realtime_iteration.RealTimeIteration`; ``inf``: its
    work is not bounded).

    Raises
    ------
    PlanError
        ``target_rest`` with a planner that holds the rest lengths, naming a string the plan
        does not move, or leaving the shape table."""

    def __init__(self, planner: AttitudePlanner, target, period_s=0.25, target_rest=None):
        self.planner, self.rpy = planner, np.asarray(target, float)
        self.model = planner.model
        self.target = target_quaternion(self.rpy)
        self.r_end = landing_coordinates(planner, target_rest)
        self.rti = RealTimeIteration(planner, budget_s=0.5 * period_s, period_s=period_s)
        self._plan = None  # the plan whose inputs are in force: the re-plans' warm start

    def first(self, t_s, x, knot_t):
        """The first plan, made before anything moves: with no period to keep, while the
        optimiser stops on its iteration limit it goes on from where it stopped, up to
        :data:`FIRST_ROUNDS` budgets (with a servo's range binding, the D-bar's three-axis
        plans on the sim-rig's limits need two to four, the re-plans from them one)."""
        x0, H0 = self.model.start(x, t_s)
        plan = self.planner.plan(self.target, knot_t, t_s, x0, H0, r_end=self.r_end)
        for _ in range(FIRST_ROUNDS - 1):
            if plan.success or ITERATION_LIMIT not in plan.message:
                break
            plan = self.planner.plan(self.target, knot_t, t_s, x0, H0, warm=plan, r_end=self.r_end)
        self._plan = plan
        return plan

    def miss(self, plan) -> float:
        """How far (rad, geodesic) the plan lands from the target."""
        return plan.landing_error_rad

    def gain_fit(self, t_s, x):
        """The momentum and wheel-gain fit, or None where a planned wheel's reaction is lost:
        the fit takes the total momentum as kept (``L = H0 - kappa W``), which such a wheel's
        spin-up changes; fitted there, ``kappa`` falls towards 0 and the plans lose the wheels'
        gyroscopic couple (the prism with its wheels: 4.5 deg off against 0.38 without the fit).
        Re-plans then take each estimate's momentum."""
        if self.planner.moves_lost_wheels:
            return None
        return MomentumGainFit(self.model, x)

    def observe(self, fit, x) -> None:
        fit.add_state(x)

    def state(self, t_s, x, schedule):
        """``(x0, H0)`` of the reduced model: the estimate's attitude and momentum, the rest
        lengths and wheel speeds the schedule commands at ``t_s``."""
        names = self.model.names[: self.model.a]
        rest = None
        if all(n in schedule.names for n in names) and names:
            rest = schedule(t_s)[[schedule.names.index(n) for n in names]]
        x0, H0 = self.model.start(x, t_s, rest)
        if schedule.wheels:
            _, _, omega_w = self.model.split(x0)  # a view: the state's wheel entries
            omega_w[:] = schedule.wheel_speeds(t_s)
        return x0, H0

    def again(self, t_s, x, knot_t, schedule, fitted):
        """``(plan, kappa)``: from the estimate's momentum, or the fitted momentum and wheel
        gain (:class:`.adapt.MomentumGainFit`) given as ``fitted``."""
        x0, H0 = self.state(t_s, x, schedule)
        kappa = 1.0
        if fitted is not None:
            H0, kappa = fitted
        self.model.wheel_gain = kappa
        plan = self.rti.plan(self.target, knot_t, t_s, x0, H0, self._plan, self.r_end)
        if plan.success:
            self._plan = plan
        return plan, kappa

    def record(self, t_s, x, plan, accepted, kappa) -> ReplanRecord:
        q = self.model.frame.attitude(self.model.model.nodes(x)[0]).quaternion
        nan = float("nan")
        return ReplanRecord(
            t_s, nan, nan, plan.plan_time_s, accepted, plan.message, kappa,
            float(angle_between(self.target, q)), plan.landing_error_rad,
        )  # fmt: skip

    def refusal(self, plan, x0, knot_t, duration_s, tolerance_rad) -> str | None:
        """None if the first plan lands within ``tolerance_rad`` and nearly still, else why it
        is refused: the reachable rotation about the target's axis."""
        if reachable(self.planner, plan, tolerance_rad):
            return None
        x, H0 = self.model.start(x0)
        return refusal(
            self.planner, plan, knot_t, x, H0, self.rpy, tolerance_rad, duration_s, self.r_end
        )

    def summary(self, plan) -> dict:
        rpy = Rotation.from_quat(plan.predicted_q, scalar_first=True).as_euler("ZYX")[::-1]
        return {"predicted_rpy_rad": [float(v) for v in rpy]}
