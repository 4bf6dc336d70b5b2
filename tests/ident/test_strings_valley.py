"""The fit moved along the strings' valley (:func:`gyrohost.ident.profile.strings_valley`) on a
cost whose answer is known: a narrow valley in log stiffness and log damping with a smooth
minimum along it, and ripples whose minima stop a local solver wherever it starts."""

import numpy as np
import pytest
from scipy.optimize import OptimizeResult

from gyrohost.ident import profile
from gyrohost.ident.params import Param

ALONG = profile.VALLEY_STEP / np.linalg.norm(profile.VALLEY_STEP)  # the valley in (k, c)
ACROSS = np.array([-ALONG[1], ALONG[0]])
RIPPLE = np.linalg.norm(profile.VALLEY_STEP) / 2  # the ripples' minima along the valley
SMOOTH_MIN = 0.1  # where the smooth cost is lowest along the valley (log units)
CURVATURE, WALL = 50.0, 1e3  # cost units per unit squared along and across


class Valley:
    """Weighted residuals whose cost is ``CURVATURE (s - SMOOTH_MIN)^2`` along the valley plus
    ``WALL c^2`` across it plus ripples of 20 units, zero at multiples of :data:`RIPPLE`."""

    def __init__(self, names=("stiffness", "damping"), smooth_min=SMOOTH_MIN):
        self.params = [Param(n, n, True, 1.0, "-") for n in names]
        self.smooth_min = smooth_min

    def __call__(self, theta):
        s, c = theta @ ALONG, theta @ ACROSS
        ripple = 20.0 * (1.0 - np.cos(2.0 * np.pi * s / RIPPLE))
        smooth = CURVATURE * (s - self.smooth_min) ** 2
        return np.sqrt(2.0 * np.array([smooth, WALL * c**2, ripple]))


def stalling_solve(problem, theta0):
    """A local solver that stops at the ripple's minimum nearest its start, on the valley's
    floor."""
    x = RIPPLE * np.round((theta0 @ ALONG) / RIPPLE) * ALONG
    r = problem(x)
    return OptimizeResult(x=x, cost=0.5 * float(r @ r))


def test_the_fit_stuck_two_ripples_off_moves_to_the_smooth_minimum():
    problem = Valley()
    stuck = stalling_solve(problem, -2 * RIPPLE * ALONG)
    sol, points = profile.strings_valley(stalling_solve, problem, stuck, np.full(2, -np.inf))
    offsets = [k for k, _, _ in points]
    # the stuck optimum and one from each valley step, which stopped there
    assert np.allclose(offsets, [-2.0, -1.0, 0.0, 1.0, 2.0])
    assert points[2][2] == stuck.cost
    # the parabola through them has its vertex at the smooth minimum (0.1), whose nearest
    # ripple minimum is one ripple (0.115) along
    assert sol.x @ ALONG == pytest.approx(RIPPLE)
    assert sol.cost < min(c for _, _, c in points)


def test_a_minimum_beyond_the_steps_is_bracketed_by_further_starts():
    step = 2 * RIPPLE  # one valley step along the valley
    problem = Valley(smooth_min=-3.2 * step)
    stuck = stalling_solve(problem, np.zeros(2))
    sol, points = profile.strings_valley(stalling_solve, problem, stuck, np.full(2, -np.inf))
    # -3 was the lowest of -4..2: -4 tried and no farther (at -4 -3.2 is inside)
    assert [round(k) for k, _, _ in points] == [-4, -3, -2, -1, 0, 1, 2]
    assert sol.x @ ALONG == pytest.approx(-3 * step)


def test_starts_below_the_bounds_are_not_tried_and_other_parameters_left_alone():
    problem = Valley()
    stuck = stalling_solve(problem, np.zeros(2))
    lower = np.array([-np.inf, -1.5 * profile.VALLEY_STEP[1]])
    _, points = profile.strings_valley(stalling_solve, problem, stuck, lower)
    assert [round(k) for k, _, _ in points] == [-1, 0, 1, 2]

    other = Valley(("J3", "bar_mass"))
    sol, points = profile.strings_valley(stalling_solve, other, stuck, np.full(2, -np.inf))
    assert sol is stuck and points == []
