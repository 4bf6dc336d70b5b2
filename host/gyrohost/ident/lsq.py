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
        Each parameter's step (units of ``theta``), positive: the upper bounds are open.
    """
    theta = np.asarray(theta, float)
    moved = theta + np.diag(np.asarray(steps, float))
    h = moved.diagonal() - theta  # the step as represented in floating point
    return np.column_stack([(r - r0) / d for r, d in zip(batch(list(moved)), h, strict=True)])


def solve(residual: Residual, batch: Batch, theta0, steps, lower, **options) -> OptimizeResult:
    """``least_squares(residual, theta0, bounds=(lower, inf), **options)`` with the Jacobian of
    :func:`forward_jacobian` over ``steps`` (shape (p,), positive) from ``batch``; the residual
    at the point of each Jacobian is the one the solver has just evaluated there."""
    steps = np.asarray(steps, float)
    if np.any(steps <= 0.0):
        raise ValueError(f"steps must be positive, got {steps.tolist()}")
    last_theta, last_r = None, None

    def remembered(theta):
        nonlocal last_theta, last_r
        last_theta, last_r = np.array(theta, float), residual(theta)
        return last_r

    def jacobian(theta):
        same = last_theta is not None and np.array_equal(last_theta, theta)
        return forward_jacobian(batch, theta, last_r if same else remembered(theta), steps)

    return least_squares(remembered, theta0, jac=jacobian, bounds=(lower, np.inf), **options)
