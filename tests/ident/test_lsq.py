"""The fits' local solve (:mod:`gyrohost.ident.lsq`) on residuals whose answer is known: the
Jacobian differences over each parameter's own step, also where the parameter is 0, and so
steps over a ripple that stops a solver differencing over scipy's relative steps."""

import numpy as np
import pytest
from scipy.optimize import least_squares

from gyrohost.ident import lsq

SMOOTH_MIN, RIPPLE_M, AMPLITUDE = 0.3, 1e-3, 0.01


def rippled(theta):
    """A smooth cost with its minimum at :data:`SMOOTH_MIN` under a ripple whose slope (63)
    is far steeper than the smooth cost's near its minimum: a fixed-step model's slack
    crossings."""
    x = theta[0]
    return np.array([x - SMOOTH_MIN, AMPLITUDE * np.sin(2.0 * np.pi * x / RIPPLE_M)])


def test_the_columns_difference_over_each_step_at_zero_in_one_batch():
    batches = []

    def batch(thetas):
        batches.append(len(thetas))
        return [np.array([t[0] ** 2, 3.0 * t[1]]) for t in thetas]

    J = lsq.forward_jacobian(batch, np.zeros(2), np.zeros(2), [0.1, 0.2])
    np.testing.assert_allclose(J, [[0.1, 0.0], [0.0, 3.0]], rtol=1e-12)
    assert batches == [2]


def test_a_rippled_cost_is_solved_to_its_smooth_minimum():
    sol = lsq.solve(
        rippled, lambda ts: [rippled(t) for t in ts], np.zeros(1), [0.05], [-1.0], xtol=1e-10
    )
    assert sol.x[0] == pytest.approx(SMOOTH_MIN, abs=0.01)
    # scipy's relative steps (sqrt(eps) at 0) read the ripple's slope and stop at its foot
    stuck = least_squares(rippled, np.zeros(1), diff_step=[0.05], bounds=([-1.0], np.inf))
    assert abs(stuck.x[0] - SMOOTH_MIN) > 0.1


def test_steps_must_be_positive():
    with pytest.raises(ValueError, match=r"steps must be positive, got \[0.1, 0.0\]"):
        lsq.solve(rippled, None, np.zeros(2), [0.1, 0.0], [-1.0, -1.0])


def test_a_start_on_a_lower_bound_still_moves():
    """A parameter fitted at its bound before (a latency at 0) starts the next fit there:
    scipy's trust region starts as wide as the start is long, and the start nudged 1e-10 off
    the bound made it 1e-15 wide, and every step was refused."""

    def quadratic(theta):
        return theta - np.array([0.04, 0.003])

    lower = np.array([-np.inf, -9.99988e-11])  # the second at its bound 0 (nominal 1e-10)
    sol = lsq.solve(
        quadratic, lambda ts: [quadratic(t) for t in ts], np.zeros(2), [1e-3, 2e-3], lower,
        xtol=1e-10,
    )  # fmt: skip
    np.testing.assert_allclose(sol.x, [0.04, 0.003], atol=1e-6)
