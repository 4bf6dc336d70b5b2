"""Consistency measures: NEES on the constraint manifold, chi-square bounds, tilt error."""

import numpy as np
from scipy.linalg import null_space
from scipy.stats import chi2


def nees(ekf, x_true):
    """Normalised estimation error squared of the present estimate against ``x_true``.

    The covariance has rank ``n - 2 beta`` (it lives in the tangent space of the constraint
    manifold), so the error and the covariance are taken in an orthonormal basis of that
    tangent space at the estimate.

    Returns
    -------
    value : float
    dof : int
    """
    T = null_space(ekf.manifold.jacobian(ekf.x))
    e = T.T @ (x_true - ekf.x)
    P = T.T @ ekf.P @ T
    return float(e @ np.linalg.solve(P, e)), T.shape[1]


def average_bounds(dof, runs, probability=0.95):
    """Two-sided chi-square bounds of the average of ``runs`` values with ``dof`` each."""
    lo, hi = chi2.ppf([(1 - probability) / 2, (1 + probability) / 2], dof * runs)
    return lo / runs, hi / runs


def tilt_error(R_est, R_true):
    """Angle between estimated and true sensor z axes, rad (R: sensor axes in the world)."""
    return float(np.arccos(np.clip(R_est[:, 2] @ R_true[:, 2], -1.0, 1.0)))


def sample_initial(ekf, x_true, rng):
    """An initial estimate drawn around ``x_true`` with the filter's initial covariance."""
    P0 = ekf.initial_covariance()
    T = null_space(ekf.manifold.jacobian(x_true))
    Pt = T.T @ P0 @ T
    e = T @ (np.linalg.cholesky(Pt) @ rng.standard_normal(Pt.shape[0]))
    return ekf.manifold.project_state(x_true + e)
