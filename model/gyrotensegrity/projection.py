"""Projection of a state onto the bar-length constraints (the constraint-preserving option).

The joints (``N P = D``) hold exactly by construction (``eta1`` is constant, Eq. 64); only the
bar lengths ``b_i^T b_i = l_i^2`` and their rates ``b_i^T b_i_dot = 0`` (Eq. 20) can drift.
Both projections are minimum-norm corrections of ``eta2`` (Gauss-Newton for the positions).
With ``b_i = eta2 u_i + const`` (``u_i`` the rows of ``E = C_b U2``) the constraint gradients
are ``2 b_i u_i^T`` and ``b_i u_i^T``, and their Gram matrix is ``(E E^T) .* (B^T B)``.
"""

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def _gram(model, B):
    G = model.EEt
    vals = G.data * np.einsum("ri,ri->i", B[:, G.row], B[:, G.col])
    return sp.csc_matrix((vals, (G.row, G.col)), shape=G.shape)


def _bars(model, q, q_dot=None):
    st = model.structure
    N = (model.N_fixed_T + model.U2 @ q.T).T
    B = N[:, st.bar_end] - N[:, st.bar_start]
    if q_dot is None:
        return B
    N_dot = np.asarray(model.U2 @ q_dot.T).T
    return B, N_dot[:, st.bar_end] - N_dot[:, st.bar_start]


def _solve(G, g):
    return np.atleast_1d(spla.spsolve(G, g))


def project_positions(model, x, rtol=1e-15, iterations=6):
    """Return x with eta2 moved (min-norm) so that every bar has its length l_i."""
    if model.beta == 0:
        return x
    L = model.layout
    x = x.copy()
    q = x[L.q].reshape(3, model.m)
    for _ in range(iterations):
        B = _bars(model, q)
        g = np.sum(B**2, axis=0) - model.l**2
        if np.max(np.abs(g) / model.l**2) <= rtol:
            break
        mu = _solve(4.0 * _gram(model, B), g)
        q = q - 2.0 * np.asarray(model.E.T @ (B * mu).T).T
    x[L.q] = q.ravel()
    return x


def project_velocities(model, x):
    """Return x with eta2_dot moved (min-norm) so that b_i . b_i_dot = 0 for every bar."""
    if model.beta == 0:
        return x
    L = model.layout
    x = x.copy()
    q = x[L.q].reshape(3, model.m)
    q_dot = x[L.q_dot].reshape(3, model.m)
    B, B_dot = _bars(model, q, q_dot)
    nu = _solve(_gram(model, B), np.sum(B * B_dot, axis=0))
    x[L.q_dot] = (q_dot - np.asarray(model.E.T @ (B * nu).T).T).ravel()
    return x


def project(model, x):
    """Positions, then velocities."""
    return project_velocities(model, project_positions(model, x))
