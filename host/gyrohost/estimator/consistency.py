"""Consistency measures: NEES on the constraint manifold, chi-square bounds, tilt error."""

from functools import lru_cache

import numpy as np
from scipy.linalg import null_space
from scipy.stats import chi2


def nees(ekf, x_true):
    """Normalised estimation error squared of the present estimate against ``x_true``.

    The covariance has rank ``n - 2 beta`` (it lives in the tangent space of the constraint
    manifold), so the error and the covariance are taken in an orthonormal basis of that
    tangent space at the estimate. ``x_true`` may leave out the trailing states no truth has
    (the wheel noise; the mounting's error where the truth does not give it): the marginal
    NEES of the rest.

    Returns
    -------
    value : float
    dof : int
    """
    n = len(x_true)  # without the wheel noise states, which no truth has
    T = null_space(ekf.manifold.jacobian(ekf.x)[:, :n])
    e = T.T @ (x_true - ekf.x[:n])
    P = T.T @ ekf.P[:n, :n] @ T
    return float(e @ np.linalg.solve(P, e)), T.shape[1]


def block_nees(ekf, x_true):
    """Marginal NEES of every block of the state against ``x_true``: the node motion in the
    tangent space of the bar constraints, the wheel speeds, the rest lengths, the gyro bias,
    the mounting's error (where it is a state and ``x_true`` has it).

    A block whose NEES sits far below its dof is conservative, far above overconfident; the
    full NEES mixes them.

    Returns
    -------
    dict, block name -> (value, dof)
    """
    L = ekf.layout
    motion = np.arange(L.q.start, L.q_dot.stop)
    T = null_space(ekf.manifold.jacobian(ekf.x)[:, motion])
    out = {"motion": _marginal(ekf, x_true, motion, T)}
    blocks = [("wheels", L.omega), ("rest", L.rest), ("bias", L.bias)]
    if L.n_mounting and len(x_true) >= L.mounting.stop:
        blocks.append(("mounting", L.mounting))
    if L.n_accel_bias and len(x_true) >= L.accel_bias.stop:
        blocks.append(("accel_bias", L.accel_bias))
    return {**out, **_entry_blocks(ekf, x_true, blocks)}


def _entry_blocks(ekf, x_true, blocks):
    """The marginal NEES of each ``(name, slice)`` of the state, entry by entry (no tangent
    space): name -> (value, dof)."""
    out = {}
    for name, part in blocks:
        idx = _indices(part)
        out[name] = _marginal(ekf, x_true, idx, np.eye(len(idx)))
    return out


def _marginal(ekf, x_true, idx, T, x=None, P=None):
    """NEES of the entries ``idx`` of the estimate (``x``, ``P``; the filter's own when None)
    in the basis ``T`` (len(idx), d) of their tangent space: (value, d)."""
    x = ekf.x if x is None else x
    P = ekf.P if P is None else P
    e = T.T @ (x_true[idx] - x[idx])
    P_t = T.T @ P[np.ix_(idx, idx)] @ T
    return float(e @ np.linalg.solve(P_t, e)), T.shape[1]


def average_bounds(dof, runs, probability=0.95):
    """Two-sided chi-square bounds of the average of ``runs`` values with ``dof`` each."""
    lo, hi = chi2.ppf([(1 - probability) / 2, (1 + probability) / 2], dof * runs)
    return lo / runs, hi / runs


def tilt_error(R_est, R_true):
    """Angle between estimated and true sensor z axes, rad (R: sensor axes in the world)."""
    return float(np.arccos(np.clip(R_est[:, 2] @ R_true[:, 2], -1.0, 1.0)))


def sample_initial(ekf, x_true, rng):
    """An initial estimate drawn around ``x_true`` (its entries only) with the filter's initial
    covariance."""
    n = len(x_true)
    P0 = ekf.initial_covariance()[:n, :n]
    T = null_space(ekf.manifold.jacobian(x_true)[:, :n])
    Pt = T.T @ P0 @ T
    e = T @ (np.linalg.cholesky(Pt) @ rng.standard_normal(Pt.shape[0]))
    return ekf.manifold.project_state(x_true + e)


def observed_nees(ekf, x, P, x_true):
    """NEES over what a truth of node positions, wheel speeds and rest lengths observes: the
    node coordinates in the tangent space of the bar lengths at ``x`` but the translation of a
    free structure (:func:`scored_positions`), the wheel speeds and the rest lengths (no
    velocities, no bias).

    Parameters
    ----------
    ekf : TensegrityEKF
        Its model, layout and manifold.
    x : ndarray, shape (n,)
    P : ndarray, shape (n, n)
    x_true : ndarray, shape (n,), only the entries named above are read

    Returns
    -------
    value : float
    dof : int
    """
    L = ekf.layout
    Tq = scored_positions(ekf, x)
    idx = np.r_[L.q.start : L.q.stop, L.omega.start : L.rest.stop]
    k = L.n_wheels + L.n_strings
    T = np.zeros((len(idx), Tq.shape[1] + k))
    T[: Tq.shape[0], : Tq.shape[1]] = Tq
    T[Tq.shape[0] :, Tq.shape[1] :] = np.eye(k)
    return _marginal(ekf, x_true, idx, T, x, P)


def observed_blocks(ekf, x_true):
    """The marginal NEES of each block :func:`observed_nees` adds up, at the present estimate:
    ``positions`` (the node coordinates in the tangent space of the bar lengths, less a free
    structure's translation: :func:`scored_positions`), ``wheels`` and ``rest`` (the rest
    lengths); a dict block name -> (value, dof), as :func:`block_nees`.

    The total is not their sum where the blocks' errors correlate; each says on its own whether
    that part of the state is conservative (far below its dof) or overconfident (far above).
    """
    L = ekf.layout
    out = {"positions": _marginal(ekf, x_true, _indices(L.q), scored_positions(ekf, ekf.x))}
    return {**out, **_entry_blocks(ekf, x_true, (("wheels", L.omega), ("rest", L.rest)))}


def scored_positions(ekf, x):
    """An orthonormal basis (3 m, d) of the node coordinates a truth scores the estimate on at
    ``x``: those along which every bar keeps its length, less the translation of the whole
    structure where it is free (every node can move; :func:`translation`).

    The model and every sensor are the same wherever the structure stands, so no measurement
    tells the filter where it is: along the translation its covariance grows from the start's
    by the unseen velocity and the acceleration noise, while the truth, on which no outside
    force acts but those the model knows, moves there as the model predicts. The error along
    those three directions stays the start's (on the simulated rig none: both start in the
    scene's shape; 1e-14 m after a run), and scored, they would put the NEES of a consistent
    filter three below its dof.
    """
    tangent = null_space(ekf.manifold.jacobian(x)[: ekf.model.beta, ekf.layout.q])
    shift = translation(ekf.model)
    if shift is None:
        return tangent
    return tangent @ null_space(shift.T @ tangent)


@lru_cache(maxsize=8)
def translation(model):
    """An orthonormal basis (3 m, 3) of the reduced coordinates (``q`` laid out by axis, as
    in the filter's state) that move every node alike, one column per axis; None where no
    such motion exists (a node held fixed). Once per model (every scored estimate asks):
    read-only."""
    U2 = model.U2.toarray()  # (n, m): N = N_fix + q U2^T
    ones = np.ones(U2.shape[0])
    column = np.linalg.lstsq(U2, ones, rcond=None)[0]
    if not np.allclose(U2 @ column, ones, rtol=0.0, atol=1e-9):
        return None
    m = U2.shape[1]
    out = np.zeros((3 * m, 3))
    for axis in range(3):
        out[axis * m : (axis + 1) * m, axis] = column / np.linalg.norm(column)
    out.flags.writeable = False
    return out


def _indices(part):
    return np.arange(part.start, part.stop)


def state_of_truth(ekf, x, N, omega_rad_s, rest_m):
    """``x`` with the node coordinates, wheel speeds and rest lengths of a truth sample.

    Parameters
    ----------
    N : ndarray, shape (3, n_scene_nodes), m, the scene's nodes in scene order
    omega_rad_s : ndarray, shape (n_w,)
    rest_m : ndarray, shape (n_s,)
    """
    L, dyn, model = ekf.layout, ekf.process.dyn, ekf.model
    scene_nodes = list(model.scene.node_names)
    N = np.asarray(N)[:, [scene_nodes.index(n) for n in model.structure.node_names]]
    U2 = ekf.model.U2.toarray()  # (n, m): N = N_fix + q U2^T
    out = np.array(x, dtype=float)
    out[L.q] = np.linalg.lstsq(U2, (N - dyn.N_fix).T, rcond=None)[0].T.ravel()
    out[L.omega] = omega_rad_s
    out[L.rest] = rest_m
    return out
