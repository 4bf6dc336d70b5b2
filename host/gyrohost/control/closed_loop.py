"""Closed loop: receding-horizon re-planning of a maneuver from the state estimate.

Law. Every ``period_s`` the :class:`Replanner` takes the estimate ``(t, x)``, reads the tilt and
the angular momentum about the tilt axis from it (or the attitude and the total momentum, for a
three-axis target: :mod:`.goals`), and re-optimises the rest of the schedule (the knots after
``t``) toward the target, with the landing time fixed (a shrinking horizon).
The new schedule starts from the rest length commanded at ``t`` and replaces the old one from
``t`` on, joined to it by the fastest move the limits allow where the two differ there (a follower
string played on a join's straight line is off the rhombus the planner starts it on), so the
servos see no jump.

Why re-planning and not a feedback law on the tilt error: the plant's gain, tilt rate per
metre of string, changes several-fold with the shape (the locked inertia falls as n1 and n3
close in) and the command must respect the servo speed and the geometry limits and land with
the shape back at rest. The planner already handles all of that; re-planning from the measured
momentum corrects a wrong model (e.g. the wheel inertia) because the current tilt rate is then
right by construction and the remaining error shrinks with the remaining horizon. A failed
re-plan keeps the previous schedule, which stays feasible (the knots do not move).

Estimate interface: any callable ``estimate() -> (t_s, x)`` returning the time (s) and a full
state of the planner's model (layout of ``gyrotensegrity.Model``). The EKF plugs in there;
:class:`TruthPlusNoise` stands in for it in SIL; :func:`ekf_estimate` adapts the EKF of
``gyrohost.estimator`` (its state ``[eta2 | eta2_dot | omega_w | gyro bias]``).
"""

import math
from dataclasses import dataclass, field

import numpy as np

from .attitude_planner import AttitudePlanner
from .errors import PlanError
from .goals import AttitudeGoal, ReplanRecord, TiltGoal
from .schedule import Schedule

__all__ = ["ReplanRecord", "Replanner", "TruthPlusNoise", "ekf_estimate"]


@dataclass
class Replanner:
    """Receding-horizon re-planner for one maneuver.

    Parameters
    ----------
    planner : Planner or AttitudePlanner
        The tilt planner (the D-bar) or the three-axis planner (any free scene).
    target : float or sequence of 3 float, rad
        The tilt, or roll, pitch, yaw of the body frame (:mod:`.goals`).
    t0_s, duration_s : float, s
        Start and length of the maneuver; it lands at ``t0_s + duration_s``.
    period_s : float, s
        Re-planning period (0.25 s = 4 Hz).
    adapt : bool
        Tilt: fit the wheel-momentum gain and the momentum from every estimate
        (:class:`.adapt.WheelGainFit`) and plan with them; otherwise plan with the momentum of
        the latest estimate and the nominal wheels. An attitude plans from the momentum of
        every estimate.
    target_rest : dict, optional
        An attitude's target shape: ``{string: rest length (m)}`` to land at
        (:class:`.goals.AttitudeGoal`).
    lag_s : float, s
        How much later the plant follows the commands than the planner's model, whose rest
        lengths and spins are the commanded ones (the servos' and the wheels' first-order lag):
        an estimate at ``t`` is planned from as the model's state at ``t - lag_s``, with the
        commands of that time, which are the ones the actuators have reached.
    real_time : bool
        Re-plans run beside a real-time loop (:class:`.maneuver.Maneuver`'s worker thread): an
        attitude re-plan's work is then bounded by the period (:class:`.goals.AttitudeGoal`).
        On a simulated clock it is not, so that its plans do not depend on the machine.
    """

    planner: object
    target: object
    t0_s: float
    duration_s: float
    period_s: float = 0.25
    adapt: bool = True
    target_rest: dict | None = None
    lag_s: float = 0.0
    real_time: bool = False
    schedule: Schedule | None = None
    records: list = field(default_factory=list)

    def __post_init__(self):
        if not (self.duration_s > 0.0 and self.period_s > 0.0):
            raise PlanError("duration_s and period_s must be positive")
        if isinstance(self.planner, AttitudePlanner):
            period_s = self.period_s if self.real_time else math.inf
            self.goal = AttitudeGoal(self.planner, self.target, period_s, self.target_rest)
        elif self.target_rest:
            raise PlanError("a target shape goes with an attitude target, not a tilt")
        else:
            self.goal = TiltGoal(self.planner, self.target)
        self.knot_t = self.planner.knot_times(self.t0_s, self.t0_s + self.duration_s)
        self.t_end_s = float(self.knot_t[-1])
        self._next_s = -np.inf
        self.fit = None

    def start(self, t_s, x):
        """The first plan, from rest (the rest shape is commanded at ``t_s``)."""
        plan = self.goal.first(t_s, x, self.knot_t)
        if not plan.success:
            raise PlanError(f"no initial plan: {plan.message}")
        self.schedule = plan.schedule
        if self.adapt:
            self.fit = self.goal.gain_fit(t_s, x)
        self._log(t_s, x, plan, True)
        self._next_s = t_s + self.period_s
        return plan

    def update(self, t_s, x) -> Schedule:
        """Re-plan if a period has passed (and the maneuver is not over); the schedule to
        follow from ``t_s`` on."""
        if self.schedule is None:
            self.start(t_s, x)
            return self.schedule
        if self.observe(t_s, x):
            self.replan(t_s, x)
        return self.schedule

    def observe(self, t_s, x) -> bool:
        """Take one estimate into the gain fit; True if a re-plan is due at ``t_s`` (the
        period is then counted as used)."""
        if self.fit is not None:
            self.goal.observe(self.fit, x)
        if self._next_s <= t_s < self.t_end_s:
            # the first grid point after t_s: a late re-plan uses up every period it overran
            self._next_s += self.period_s * (np.floor((t_s - self._next_s) / self.period_s) + 1.0)
            return True
        return False

    def fitted(self):
        """``(momentum, kappa)`` of the gain fit, or None without adaptation."""
        return None if self.fit is None else self.fit.estimate()[:2]

    def replan(self, t_s, x, fitted=None):
        """Re-optimise the rest of the schedule from the state ``x`` at ``t_s``; ``fitted``
        (momentum, kappa) defaults to the gain fit's current values (:meth:`fitted`)."""
        fitted = self.fitted() if fitted is None else fitted
        t_plan = max(t_s - self.lag_s, self.t0_s)  # the commands the actuators have reached
        plan, kappa = self.goal.again(t_plan, x, self.knot_t, self.schedule, fitted)
        if plan.success:  # joined: a follower string inside a join is off its geometry
            self.schedule = self.schedule.join(plan.schedule, t_s, self.planner.limits)
        self._log(t_s, x, plan, plan.success, kappa)
        return plan

    def _log(self, t_s, x, plan, accepted, kappa=1.0):
        self.records.append(self.goal.record(t_s, x, plan, accepted, kappa))


class TruthPlusNoise:
    """Stand-in estimator for SIL: the truth state plus white Gaussian noise.

    Parameters
    ----------
    stepper : gyrotensegrity.Stepper
        The truth (its ``t`` and ``x`` are read).
    position_std_m, velocity_std_m_s : float
        Noise on the node coordinates (m) and their rates (m/s) in ``x``; wheel states are
        passed through.
    seed : int
    """

    def __init__(self, stepper, position_std_m=1e-3, velocity_std_m_s=2e-3, seed=0):
        self.stepper = stepper
        self.std = (position_std_m, velocity_std_m_s)
        self.rng = np.random.default_rng(seed)

    def __call__(self):
        L = self.stepper.model.layout
        x = self.stepper.x.copy()
        x[L.q] += self.rng.normal(0.0, self.std[0], x[L.q].size)
        x[L.q_dot] += self.rng.normal(0.0, self.std[1], x[L.q_dot].size)
        return self.stepper.t, x


def ekf_estimate(ekf):
    """An ``estimate() -> (t_s, x)`` reading a ``gyrohost.estimator`` EKF.

    The filter state is ``[vec(eta2) (3 m) | vec(eta2_dot) (3 m) | omega_w (n_w) | b_g (3)]``;
    the model state gets the same coordinates, zero wheel angles (nothing here depends on
    them) and the spins of the torque-driven wheels.
    """
    model = ekf.model
    L = model.layout
    n_w = len(model.wheel_bars)

    def estimate():
        xf = np.asarray(ekf.x, float)
        omega_w = xf[L.q_dot.stop : L.q_dot.stop + n_w]
        x = np.concatenate([xf[: L.q_dot.stop], np.zeros(n_w), omega_w[model.torque_wheels]])
        return float(ekf.t), x

    return estimate
