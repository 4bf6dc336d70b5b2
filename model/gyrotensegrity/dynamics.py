"""Per-evaluation dynamics: the right-hand side ``f(t, x, u, params)``.

Equation numbers refer to Goyal, Chen, Majji, Skelton, "Gyroscopic Tensegrity Robots".
Matrices carry the paper's names; ``(3, n)`` node matrices are products with the sparse
connectivity matrices of the compiled :class:`~gyrotensegrity.model.Model` (``params``).
"""

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .errors import SceneError
from .model import Model


@dataclass(frozen=True)
class Evaluation:
    """Everything one right-hand-side evaluation computes (for diagnostics and tests).

    N, N_dot, N_ddot : (3, n) m, m/s, m/s^2 (N_ddot = eta2_ddot U2^T);
    gamma : (alpha,) string force densities, N/m; lam : (beta,) bar force densities, N/m;
    Omega : (3, c) Lagrange multipliers, N; omega_w, omega_w_dot : (n_w,) wheel spin rad/s, rad/s^2.
    """

    N: np.ndarray
    N_dot: np.ndarray
    N_ddot: np.ndarray
    gamma: np.ndarray
    lam: np.ndarray
    Omega: np.ndarray
    omega_w: np.ndarray
    omega_w_dot: np.ndarray
    eta2_ddot: np.ndarray


def right(matrix_T: sp.spmatrix, X: np.ndarray) -> np.ndarray:
    """``X @ matrix`` for a (3, k) dense X, given ``matrix_T`` = matrix^T (sparse, CSR)."""
    return np.asarray(matrix_T @ X.T).T


def string_force_densities(model: Model, S, S_dot, rest_length):
    """gamma (alpha,) N/m of linear elastic, tension-only strings with damping.

    Tension ``k (s - s0) + c s_dot`` while the string is longer than its rest length, never
    negative (a string does not push); zero while slack (damping off, as in MOTES).
    """
    s = np.linalg.norm(S, axis=0)
    s_dot = np.einsum("ij,ij->j", S, S_dot) / s
    tension = model.k_s * (s - rest_length) + model.c_s * s_dot
    tension = np.where(s > rest_length, np.maximum(tension, 0.0), 0.0)
    return tension / s


def gyroscopic_forces(model: Model, B, B_dot, omega_w):
    """The wheel term of W_T (Eq. 59): columns J_a omega_w b x b_dot / l (Eq. 34), times C_b."""
    i = model.wheel_bars
    G = np.zeros_like(B)
    G[:, i] = np.cross(B[:, i], B_dot[:, i], axis=0) * (model.J_a[i] * omega_w / model.l[i])
    return right(model.C_b_T, G)


def evaluate(t, x, u, params: Model) -> Evaluation:
    """Evaluate the dynamics (Eqs. 53-59, with Eqs. 60-68 when there are constraints).

    Raises
    ------
    PrunedTermError
        When a wheel spins or is driven on a model built with ``omit=("gyroscopic",)``.
    """
    model = params
    if model.rig is not None:
        raise SceneError(
            f"{model.scene.source}: rig_fidelity: evaluate() is the paper's model only"
        )
    st = model.structure
    model.check_omitted(x[model.layout.omega], u[model.alpha :])
    N, N_dot = model.nodes(x)
    B = N[:, st.bar_end] - N[:, st.bar_start]  # B = N C_b^T
    B_dot = N_dot[:, st.bar_end] - N_dot[:, st.bar_start]
    # |b_i|^2 where the paper writes l_i^2 in lambda (Eqs. 58, 62): equal on the constraint
    # manifold; off it, this keeps b^T b_ddot = -|b_dot|^2 exact, so bar-length drift stays
    # neutral instead of growing exponentially in compressed bars.
    b2 = np.sum(B**2, axis=0)

    # String forces -S gamma^ C_s (Eqs. 51-52).
    S = N[:, st.string_end] - N[:, st.string_start]
    S_dot = N_dot[:, st.string_end] - N_dot[:, st.string_start]
    gamma = string_force_densities(model, S, S_dot, u[: model.alpha])
    F = model.W - right(model.C_s_T, S * gamma)

    # W_T (Eq. 59): external forces plus gyroscopic forces of the wheels.
    omega_w = model.wheel_speeds(x, u)
    if "gyroscopic" in model.terms:
        F = F + gyroscopic_forces(model, B, B_dot, omega_w)

    # Bar force densities lambda (Eq. 58 / 62 without Omega), then the unconstrained total force.
    FC = F[:, st.bar_end] - F[:, st.bar_start]  # F C_b^T
    lam = -(model.J_t * np.sum(B_dot**2, axis=0) + 0.5 * np.sum(B * FC, axis=0)) / b2
    F_total = F + right(model.C_b_T, B * lam)  # W_T - N K_s with lambda so far

    Omega = np.zeros((3, model.c))
    if "multipliers" in model.terms:
        Omega, lam_Omega = solve_multipliers(model, B, b2, F_total)
        lam = lam + lam_Omega
        F_total = F_total + right(model.C_b_T, B * lam_Omega)

    # Reduced-order dynamics (Eq. 68): eta2_ddot (U2^T M_s U2) = (W_T - N K_s) U2.
    f_red = np.asarray(model.U2.T @ F_total.T)  # (m, 3)
    eta2_ddot = model.M_red_lu.solve(f_red).T
    N_ddot = right(model.U2, eta2_ddot)

    # Wheel spin (Eq. 55): tau_b = J_a l^2 omega_w_dot = J_3 omega_w_dot, torque-driven wheels.
    omega_w_dot = np.zeros(len(model.wheel_bars))
    tq = model.torque_wheels
    if len(tq):
        torque = u[model.alpha + tq]
        omega_w_dot[tq] = torque / model.J3[model.wheel_bars[tq]]
    return Evaluation(N, N_dot, N_ddot, gamma, lam, Omega, omega_w, omega_w_dot, eta2_ddot)


def solve_multipliers(model: Model, B, b2, F_total):
    """Lagrange multipliers Omega (3, c) from Eq. 67 and the bar force densities they add.

    Eq. 67 post-multiplied by the constant Sigma1 V^T (so U1 becomes P):
    N K_s M_s^-1 P - Omega P^T M_s^-1 P = W_T M_s^-1 P, where K_s contains lambda(Omega)
    (Eq. 62). J_t enters through M_s and the gyroscopic forces through W_T, exactly as in the
    dynamics. ``b2`` (beta,) is |b_i|^2 (see :func:`evaluate`). Returns (Omega, lam_Omega) with
    lam_Omega (beta,) N/m.
    """
    N_ddot_0 = right(model.M_s_inv, F_total)  # unconstrained accelerations, F_total M_s^-1
    rhs = -np.asarray(model.P_T @ N_ddot_0.T)  # (c, 3): -N_ddot_0 P, transposed
    bb = np.einsum("ri,si->irs", B, B / b2)[model.omega_pairs_bar].reshape(-1, 9)
    rows0, cols0, vals0 = model.omega_const
    vals = np.concatenate([vals0, (model.omega_pairs_coef[:, None] * bb).ravel()])
    rows = np.concatenate([rows0, model.omega_pairs_rows])
    cols = np.concatenate([cols0, model.omega_pairs_cols])
    K = sp.csc_matrix((vals, (rows, cols)), shape=(3 * model.c, 3 * model.c))
    Omega = spla.spsolve(K, rhs.ravel()).reshape(model.c, 3).T
    OH = right(model.H, Omega)  # Omega P^T C_b^T, (3, beta)
    lam_Omega = -0.5 * np.sum(B * OH, axis=0) / b2
    return Omega, lam_Omega


def rhs(t, x, u, params: Model):
    """dx/dt of the state ``x`` under input ``u`` (see :mod:`gyrotensegrity.model` for layouts).

    Parameters
    ----------
    t : float, s
    x : ndarray, shape (layout.size,)
    u : ndarray, shape (alpha + n_w,): rest lengths (m), then wheel speeds (rad/s) or torques (N m)
    params : Model

    Returns
    -------
    ndarray, shape (layout.size,)
    """
    model = params
    if model.rig is not None:
        return model.rig.rhs(t, x, u)
    L = model.layout
    ev = evaluate(t, x, u, model)
    dx = np.empty_like(x)
    dx[L.q] = x[L.q_dot]
    dx[L.q_dot] = ev.eta2_ddot.ravel()
    dx[L.theta] = ev.omega_w
    dx[L.omega] = ev.omega_w_dot[model.torque_wheels]
    return dx
