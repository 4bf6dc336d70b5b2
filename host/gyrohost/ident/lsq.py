"""The fits' local solve: ``scipy.optimize.least_squares`` with a Jacobian by forward differences
over each parameter's own step, its columns evaluated as one batch.

scipy's finite differences take ``diff_step`` relative to ``|theta|`` (scipy 1.17,
``optimize._numdiff._compute_absolute_step``), and ``sqrt(eps)`` where ``theta`` is 0: at the
nominal parameters, where every ``theta`` is 0, each column would difference over 1.5e-8 and
read one jump of the fixed-step model's rough cost (:mod:`.profile`) instead of its slope over
the parameter's step (:attr:`.params.Param.step`). The columns are independent runs of the
model, so a problem that evaluates several parameter vectors at once (the filter fit's process
pool) computes a Jacobian in the time of a few.
"""

from collections.abc import Callable, Sequence

import numpy as np
from scipy.optimize import OptimizeResult, least_squares

Residual = Callable[[np.ndarray], np.ndarray]
Batch = Callable[[Sequence[np.ndarray]], list]


def forward_jacobian(batch: Batch, theta, r0: np.ndarray, steps) -> np.ndarray:
    """Forward differences of a residual at ``theta``, shape (n, p).

    Parameters
    ----------
    batch : callable
        ``batch(thetas) -> list`` of the residuals, shape (n,) each, of the parameter vectors
        ``thetas``, in order.
    theta : ndarray, shape (p,)
    r0 : ndarray, shape (n,)
        The residual at ``theta``.
    steps : ndarray, shape (p,)
        Each parameter's step (units of ``theta``), positive: forward also from an upper bound
        (the node noise's, :func:`.params.accel_psd_ceiling`, bounds the fit's answer; the
        filter holds a step past it).
    """
    theta = np.asarray(theta, float)
    moved = theta + np.diag(np.asarray(steps, float))
    h = moved.diagonal() - theta  # the step as represented in floating point
    return np.column_stack([(r - r0) / d for r, d in zip(batch(list(moved)), h, strict=True)])


FEASIBLE_MARGIN = 1e-10
"""scipy's ``make_strictly_feasible`` margin (relative, at least absolute): a start this near a
bound is moved this far inside it (scipy 1.17, ``least_squares``)."""


def off_the_bounds(theta0, lower, upper, steps) -> np.ndarray:
    """``theta0`` with each parameter that starts on its lower bound (within
    :data:`FEASIBLE_MARGIN`) one step above it, on its upper bound one step below it.

    scipy's trust region starts as wide as the scaled start is long (``trf``: ``Delta =
    norm(x0 ...)``, 1 only for a start of exactly 0). A fit that starts from 0 with a parameter
    on its bound (a latency fitted to 0 by the stage before) has its start nudged 1e-10 off
    the bound, a first trust region some 1e-15 wide, and every step refused until ``xtol``
    ends it where it began. One step inside, the region starts a step wide and grows."""
    theta0 = np.array(theta0, float)
    for bound, inward in ((np.asarray(lower, float), 1.0), (np.asarray(upper, float), -1.0)):
        gap = inward * (theta0 - bound)
        on = np.isfinite(bound) & (gap <= FEASIBLE_MARGIN * np.maximum(1.0, np.abs(bound)))
        theta0[on] = bound[on] + inward * steps[on]
    return theta0


def solve(
    residual: Residual, batch: Batch, theta0, steps, lower, upper=np.inf, **options
) -> OptimizeResult:
    """``least_squares(residual, theta0, bounds=(lower, upper), **options)`` with the Jacobian of
    :func:`forward_jacobian` over ``steps`` (shape (p,), positive) from ``batch``; the residual
    at the point of each Jacobian is the one the solver has just evaluated there."""
    steps = np.asarray(steps, float)
    if np.any(steps <= 0.0):
        raise ValueError(f"steps must be positive, got {steps.tolist()}")
    theta0 = off_the_bounds(theta0, lower, np.broadcast_to(upper, steps.shape), steps)
    last_theta, last_r = None, None

    def remembered(theta):
        nonlocal last_theta, last_r
        last_theta, last_r = np.array(theta, float), residual(theta)
        return last_r

    def jacobian(theta):
        same = last_theta is not None and np.array_equal(last_theta, theta)
        return forward_jacobian(batch, theta, last_r if same else remembered(theta), steps)

    return least_squares(remembered, theta0, jac=jacobian, bounds=(lower, upper), **options)
