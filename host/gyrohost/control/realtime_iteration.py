"""Re-plans of bounded work: a real-time iteration of the attitude planner.

A closed loop re-plans every period (0.25 s) from the estimate, and a re-plan that is not done
within its period is of no use. :meth:`AttitudePlanner.plan` runs SLSQP to convergence: its time
depends on how far the estimate is from the plan in force (0.1-0.6 s warm on the D-bar). This
re-plan does a fixed amount of work instead, so that its time is bounded by construction:

- at most ``iterations`` Gauss-Newton steps (fewer when ``budget_s`` runs out) from the warm
  start (the plan in force, on the same knots). Each linearises, around the present inputs,
  the landing residuals (the attitude error ``2 vec(q_target^-1 q_K)`` and the body rate left
  at the landing, times ``drift_s``: the angle it turns in that time after the landing) and
  every limit, with the complex-step sensitivities the planner already computes (one batched
  integration), and solves the small quadratic programme of the step (no simulation in it; at
  most :data:`QP_ITERATIONS`);
- each step is tried whole, then halved at most :data:`HALVINGS` times, and taken only if the
  nonlinear landing cost falls and no limit is violated more than before (one batched
  integration per try, which the next step's linearisation reuses);
- the work stops where its next piece (a step of the batched integration, an iteration of the
  step's programme) would end past the period ``period_s``, judged by the piece before it
  (:mod:`.deadline`): on a loaded machine the re-plan ends in time with the steps taken so far.

The result is a plan that is better than the plan in force from the same state, or a failed
plan: the closed loop then keeps the schedule in force, which stays within the limits (its
knots do not move).

Why the landing rate is a cost here and a constraint in the first plan: the first plan starts
from rest on the nominal model, where landing with no rate is reachable; a re-plan starts from
an estimate of a plant the model gets slightly wrong, from which a hard landing-rate bound may
be unreachable in the time left, and a programme without a solution would give no plan at all.
"""

import math
import time
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from .attitude_model import quaternion_product
from .attitude_planner import FEASIBLE, AttitudePlan, AttitudePlanner, conjugate
from .deadline import NONE, Deadline
from .errors import PastDeadline

DRIFT_S = 10.0
"""Weight of the landing rate: the time (s) over which it is judged; the first plan's landing
rate bound is set so that it drifts less than the refusal's 0.005 rad in this time."""
ITERATIONS = 2
"""Gauss-Newton steps per re-plan at most. One is a real-time iteration's; the second takes
most of what the first leaves from an estimate that moved the plan by degrees."""
HALVINGS = 2
"""Halvings of a step that does not improve the plan."""
QP_ITERATIONS = 60
"""SLSQP iterations on one step's quadratic programme (linear algebra of tens of variables)."""
RESULT_RESERVE = 0.05
"""Share of the period left after the cut for the result: its schedule from the kept
trajectory (about 1 ms of the D-bar's 250 ms) and one piece's jitter past its judged time."""


@dataclass(frozen=True)
class RealTimeIteration:
    """Bounded re-plans of an :class:`AttitudePlanner` (see the module docstring).

    Parameters
    ----------
    planner : AttitudePlanner
    iterations : int
    drift_s : float, s
    budget_s : float, s
        A step after the first is begun only if it would end within this time from the start
        of the re-plan, judged by the step before it (a loaded machine takes fewer steps).
    period_s : float, s
        The re-planning period: a re-plan past it is of no use. The work is cut where its next
        piece (an integrator step, an iteration of a step's programme) would end past the
        period less :data:`RESULT_RESERVE` of it (:class:`.deadline.Deadline`), and the re-plan
        returns the steps taken before (a failed plan if none: the schedule in force stays).
    """

    planner: AttitudePlanner
    iterations: int = ITERATIONS
    drift_s: float = DRIFT_S
    budget_s: float = math.inf
    period_s: float = math.inf

    def plan(
        self, target_q, knot_t_s, t_start_s, x0, H0, warm: AttitudePlan, r_end=None
    ) -> AttitudePlan:
        """A re-plan of the intervals after ``t_start_s`` from the state ``x0`` (arguments as
        :meth:`AttitudePlanner.plan`, ``r_end`` the landing coordinates of a target shape),
        starting from ``warm``: successful only if it improves on ``warm``'s inputs from this
        state within the limits."""
        start = time.perf_counter()
        problem = self.planner._problem(target_q, knot_t_s, t_start_s, x0, H0, r_end)
        problem.deadline = Deadline(start + (1.0 - RESULT_RESERVE) * self.period_s)
        z, taken, cut = problem.guess(warm), 0, ""
        try:
            problem.keep(z)
            for _ in range(self.iterations if problem.n_z else 0):
                begun = time.perf_counter()
                step = self._step(problem, z)
                better = None if step is None else self._try(problem, z, step)
                if better is None:
                    break
                z, taken = better, taken + 1
                problem.keep(z)
                now = time.perf_counter()
                if now - start + (now - begun) > self.budget_s:
                    break
        except PastDeadline:
            cut = "; cut at the period"
        problem.deadline = NONE
        # each step taken lowered the cost and violates no limit more than the warm start
        ok = taken > 0
        message = f"{taken} of {self.iterations} steps taken{cut}" + (
            "" if ok else ": no better plan"
        )
        return problem.result(z, ok, message, time.perf_counter() - start)

    def residuals(self, problem, z):
        """Landing residuals (3 attitude + 3 rate, rad) at inputs ``z`` and their Jacobian
        (6, n_z)."""
        X, _ = problem.trajectory(z)
        q = X[:, -1, :4]
        e = quaternion_product(np.moveaxis(conjugate(problem.target), -1, 0), np.moveaxis(q, -1, 0))
        err = 2.0 * np.moveaxis(e[1:], 0, -1) / np.sqrt(np.sum(q * q, axis=-1))[:, None]
        rate = self.drift_s * self.planner.landing_rate(X[:, -1], problem.H0)
        return problem._value_grad(np.concatenate([err, rate], axis=1))

    def cost(self, problem, z) -> float:
        """The landing cost (rad^2) and the effort at inputs ``z``."""
        r, _ = self.residuals(problem, z)
        return float(r @ r + np.real(problem._effort(z.astype(complex)[None]))[0])

    def _step(self, problem, z):
        """The Gauss-Newton step from ``z``: the minimum of the linearised landing cost plus
        the effort within the linearised limits and the input boxes; None if the programme
        has no solution.

        Solved in the coordinates ``y`` where the programme's Hessian is the identity
        (``d = M y``, ``M^T 2 (J^T J + C) M = I``): SLSQP starts from the identity as its
        Hessian, so its first step is the exact one and it stops at the next iterate."""
        r, J = self.residuals(problem, z)
        g, G = problem.margins(z)
        c = np.real(problem._effort(np.eye(problem.n_z, dtype=complex)))  # effort per z_j^2
        L = np.linalg.cholesky(2.0 * (J.T @ J + np.diag(c)))
        M = np.linalg.inv(L).T
        JM, GM = J @ M, G @ M

        def fun(y):
            d = M @ y
            res = r + JM @ y
            return res @ res + c @ (z + d) ** 2, 2.0 * (JM.T @ res + M.T @ (c * (z + d)))

        eye, deadline = np.eye(problem.n_z), problem.deadline
        deadline.begin()
        constraints = [
            {"type": "ineq", "fun": lambda y: g + GM @ y, "jac": lambda y: GM},
            {"type": "ineq", "fun": lambda y: 1.0 - z - M @ y, "jac": lambda y: -M},
            {"type": "ineq", "fun": lambda y: 1.0 + z + M @ y, "jac": lambda y: eye @ M},
        ]
        if problem.p.mode != "wheels" and problem.p.model.a:
            h, H = problem.equalities(z)
            HM = H @ M
            constraints.append({"type": "eq", "fun": lambda y: h + HM @ y, "jac": lambda y: HM})
        res = optimize.minimize(
            fun,
            np.zeros_like(z),
            jac=True,
            method="SLSQP",
            constraints=constraints,
            options={"maxiter": QP_ITERATIONS, "ftol": 1e-12},
            callback=lambda y: deadline.check(),
        )
        step = M @ res.x
        return step if np.isfinite(step).all() and res.status in (0, 9) else None

    def _try(self, problem, z, step):
        """``z`` plus the step or one of its halves that lowers the cost without violating a
        limit more than ``z`` does; None if none does."""
        base, allowed = self.cost(problem, z), max(_violation(problem, z), FEASIBLE)
        for k in range(HALVINGS + 1):
            trial = np.clip(z + step / 2.0**k, -1.0, 1.0)
            if _violation(problem, trial) <= allowed and self.cost(problem, trial) < base:
                return trial
        return None


def _violation(problem, z) -> float:
    """The largest violation of a limit or of the rest lengths' return at inputs ``z``."""
    worst = -min(float(np.min(problem.margins(z)[0], initial=0.0)), 0.0)
    if problem.p.mode != "wheels" and problem.p.model.a:
        worst = max(worst, float(np.max(np.abs(problem.equalities(z)[0]))))
    return worst
