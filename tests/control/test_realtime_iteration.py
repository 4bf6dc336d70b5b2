"""Re-plans of bounded work: at most ``iterations`` Gauss-Newton steps, fewer when the budget
runs out, each taken only if it lowers the landing cost within the limits."""

import numpy as np
import pytest

from gyrohost.control import Limits
from gyrohost.control.adapt import MomentumGainFit
from gyrohost.control.attitude_planner import AttitudePlanner, target_quaternion
from gyrohost.control.deadline import NONE, Deadline
from gyrohost.control.errors import PastDeadline
from gyrohost.control.realtime_iteration import RealTimeIteration
from gyrohost.control.shape_attitude import AttitudeModel, quaternion_product_batch

TARGET_DEG = (10.0, -20.0, -27.27)


@pytest.fixture(scope="module")
def setting(dbar):
    model = AttitudeModel(dbar, limits=Limits())
    planner = AttitudePlanner(model)
    x0, H0 = model.start(dbar.initial_state())
    knots = planner.knot_times(0.0, 4.0)
    q = target_quaternion(np.radians(TARGET_DEG))
    return planner, knots, q, H0, planner.plan(q, knots, 0.0, x0, H0)


def perturbed(plan, k):
    """The plan's state at knot ``k`` turned 0.02 rad about x: where a re-plan starts when the
    estimate is off the plan."""
    x = plan.states[k].copy()
    x[:4] = quaternion_product_batch(x[:4], np.array([np.cos(0.01), np.sin(0.01), 0.0, 0.0]))
    return x


def test_a_replan_lands_nearer_than_the_plan_in_force_from_the_same_state(setting):
    planner, knots, q, H0, plan = setting
    rti = RealTimeIteration(planner)
    x, t = perturbed(plan, 2), float(knots[2])
    as_is = RealTimeIteration(planner, iterations=0).plan(q, knots, t, x, H0, plan)
    again = rti.plan(q, knots, t, x, H0, plan)
    assert not as_is.success and as_is.message.startswith("0 of 0 steps")  # nothing improved
    assert again.success and again.message in ("1 of 2 steps taken", "2 of 2 steps taken")
    assert again.landing_error_rad < 0.5 * as_is.landing_error_rad
    assert again.schedule.problems(Limits()) == []
    assert again.knot_t_s[0] == t and np.array_equal(again.knot_t_s[1:], knots[3:])


def test_the_budget_stops_after_the_first_step(setting):
    planner, knots, q, H0, plan = setting
    x, t = perturbed(plan, 2), float(knots[2])
    one = RealTimeIteration(planner, budget_s=0.0).plan(q, knots, t, x, H0, plan)
    assert one.message == "1 of 2 steps taken"


def test_a_replan_cut_at_the_period_keeps_the_steps_taken_before(setting, monkeypatch):
    """Past the period the work stops inside the next step, and the re-plan is the one of the
    steps before it, as if it had been asked for no more."""
    planner, knots, q, H0, plan = setting
    x, t = perturbed(plan, 2), float(knots[2])
    one = RealTimeIteration(planner, iterations=1).plan(q, knots, t, x, H0, plan)
    tries = []
    whole_try = RealTimeIteration._try

    def period_over_at_second_try(self, problem, z, step):
        tries.append(z)
        if len(tries) == 2:
            problem.deadline.at_s = 0.0  # the period ended before this try
        return whole_try(self, problem, z, step)

    monkeypatch.setattr(RealTimeIteration, "_try", period_over_at_second_try)
    cut = RealTimeIteration(planner, period_s=60.0).plan(q, knots, t, x, H0, plan)
    assert cut.success and cut.message == "1 of 2 steps taken; cut at the period"
    np.testing.assert_array_equal(cut.inputs, one.inputs)
    assert cut.schedule.problems(Limits()) == []


def test_a_replan_cut_before_its_first_step_keeps_the_plan_in_force(setting):
    planner, knots, q, H0, plan = setting
    x, t = perturbed(plan, 2), float(knots[2])
    cut = RealTimeIteration(planner, period_s=1e-9).plan(q, knots, t, x, H0, plan)
    assert not cut.success
    assert cut.message == "0 of 2 steps taken; cut at the period: no better plan"


def test_a_deadline_stops_a_piece_that_would_end_past_it(monkeypatch):
    clock = [100.0]
    monkeypatch.setattr("gyrohost.control.deadline.time.perf_counter", lambda: clock[0])
    NONE.check()
    with pytest.raises(PastDeadline, match="past the deadline"):
        Deadline(99.0).check()
    late = Deadline(100.020)
    late.check()
    clock[0] = 100.015  # this piece took 15 ms: the next would end past the deadline
    with pytest.raises(PastDeadline, match="0.0100 s past"):
        late.check()
    late.begin()  # a new loop: judged by nothing before it, and 5 ms are left
    late.check()


class Exact(MomentumGainFit):
    """Samples made with the fit's own law at a known momentum and gain: the wheels' momentum
    ``W`` given, the structure's ``L = H0 - kappa W``."""

    H0, KAPPA = np.array([0.001, 0.005, -0.002]), 1.3

    def split(self, x):
        if np.size(x) != 3:  # the model's start: the prior
            return super().split(x)
        wheels = np.asarray(x, float)
        return self.H0 - self.KAPPA * wheels, wheels


def test_the_momentum_fit_recovers_momentum_and_gain(dbar):
    model = AttitudeModel(dbar, limits=Limits())
    fit = Exact(model, dbar.initial_state())  # its momentum the prior: off the truth
    for angle in np.linspace(0.0, 1.0, 300):  # the prior's pull falls as 1 / samples
        fit.add_state((1.0 + angle) * 0.004 * np.array([np.sin(angle), np.cos(angle), 0.0]))
    H0, kappa, std = fit.estimate()
    assert kappa == pytest.approx(Exact.KAPPA, abs=1e-3) and std < 0.05
    np.testing.assert_allclose(H0, Exact.H0, atol=1e-5)
