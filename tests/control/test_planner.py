"""The planner: constraints hold, target reached in its model, gradients, bad requests."""

import numpy as np
import pytest
from scipy import optimize

from gyrohost.control import Limits, PlanError, Planner, plan
from gyrohost.control.planner import _Problem
from gyrohost.resources import shipped
from gyrotensegrity import Model, load_scene


def check_limits(p, planner, limits):
    s = p.schedule
    rates = np.abs(np.diff(s.rest_length, axis=0)) / np.diff(s.t)[:, None]
    assert rates.max() <= limits.max_speed_m_s * (1 + 1e-6)
    d13, d24 = s.rest_length.T
    np.testing.assert_allclose(d13**2 + d24**2, 4 * planner.dbar.l**2, rtol=1e-9)  # rhombus
    assert min(d13.min(), d24.min()) >= limits.min_diagonal_m - 1e-12


@pytest.mark.parametrize(("target", "duration"), [(-0.3, 4.0), (0.15, 4.0), (-0.1, 2.5)])
def test_plan_reaches_target_within_limits(dbar, target, duration):
    limits = Limits(max_speed_m_s=0.05)
    p = plan(dbar, target, duration, limits)
    assert p.success, p.message
    assert p.predicted_tilt_rad == pytest.approx(target, abs=1e-3)
    check_limits(p, Planner(dbar, limits), limits)
    rest = p.schedule(0.0)
    np.testing.assert_allclose(p.schedule(duration), rest, atol=1e-12)  # lands at rest
    np.testing.assert_allclose(rest[0], 0.43105229381822, atol=1e-9)


def test_unreachable_target_stays_within_limits(dbar, planner):
    p = plan(dbar, -2.0, 3.0)
    assert abs(p.predicted_tilt_rad) < 1.0  # cannot get there at 0.05 m/s in 3 s
    check_limits(p, planner, planner.limits)


def test_faster_servos_reach_further(dbar):
    slow = plan(dbar, -2.0, 3.0, Limits(max_speed_m_s=0.05))
    fast = plan(dbar, -2.0, 3.0, Limits(max_speed_m_s=0.1))
    assert fast.predicted_tilt_rad < slow.predicted_tilt_rad < 0.0


def test_cost_gradient_and_constraint_jacobian(dbar, planner):
    kt = planner.knot_times(0.0, 4.0)
    H = planner.dbar.momentum(dbar.initial_state(), dbar.input_at(0.0))
    pr = _Problem(planner, kt, 0.0, H, dbar.spin0, planner.dbar.d_rest, -0.3)
    z = np.array([0.40, 0.35, 0.33, 0.36, 0.40])
    g = pr.cost(z)[1]
    num = optimize.approx_fprime(z, lambda v: pr.cost(v)[0], 1e-7)
    np.testing.assert_allclose(g, num, rtol=1e-3, atol=1e-4 * np.abs(g).max())
    J = pr.speed_jacobian(z)
    numJ = np.array(
        [
            optimize.approx_fprime(z, lambda v, i=i: pr.speed_margins(v)[i], 1e-7)
            for i in range(J.shape[0])
        ]
    )
    np.testing.assert_allclose(J, numJ, atol=1e-6)


def test_bad_requests(dbar, planner):
    with pytest.raises(PlanError, match="duration_s"):
        plan(dbar, -0.3, 0.0)
    with pytest.raises(PlanError, match="finite"):
        plan(dbar, float("nan"), 3.0)
    for limits in (Limits(max_length_m=0.42), Limits(min_diagonal_m=0.44)):
        with pytest.raises(PlanError, match="no n1-n3 length"):
            Planner(dbar, limits)
    kt = planner.knot_times(0.0, 2.0)
    with pytest.raises(PlanError, match="not before the end"):
        planner.plan_from_state(-0.1, dbar.initial_state(), 2.5, kt)
    with pytest.raises(PlanError):
        Planner(Model(load_scene(shipped("scene", "double-pendulum"))))
