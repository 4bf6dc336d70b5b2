"""Batched, dense, complex-step-safe evaluation of the gyroscopic tensegrity dynamics.

A wrapper around a compiled :class:`gyrotensegrity.Model`: it takes the model's constant
matrices (connectivity, ``M_s^-1``, ``U2``, the reduced mass matrix, the constant parts of the
multiplier system of Eq. 67) as small dense arrays and evaluates the same equations as
:func:`gyrotensegrity.dynamics.evaluate` for a whole batch of states at once. The estimator
needs this for speed (one batched call instead of 30 sparse ones for a Jacobian) and for the
complex step (every operation is analytic in its complex argument: norms are ``sqrt(sum(x*x))``
without conjugation and the branch tests of slack strings use real parts).

Tests compare it with :func:`gyrotensegrity.rhs` to round-off
(tests/estimator/test_process_model.py).
"""

import numpy as np

from .errors import EstimatorConfigError


class BatchDynamics:
    """Dense batched right-hand side of a compiled model.

    Parameters
    ----------
    model : gyrotensegrity.Model

    Notes
    -----
    Node matrices are batched as ``(K, 3, n)``; reduced coordinates ``eta2`` as ``(K, 3, m)``.
    """

    def __init__(self, model):
        st = model.structure
        self.model = model
        self.m, self.n, self.beta, self.alpha = model.m, model.n, model.beta, model.alpha
        self.c = model.c
        self.U2T = model.U2.toarray().T  # (m, n)
        self.N_fixed = np.asarray(model.N_fixed_T).T  # (3, n)
        self.C_b = st.C_b.toarray()  # (beta, n)
        self.C_s = st.C_s.toarray()  # (alpha, n)
        self.bar_start, self.bar_end = st.bar_start, st.bar_end
        self.string_start, self.string_end = st.string_start, st.string_end
        self.W = np.asarray(model.W)
        self.k_s, self.c_s = model.k_s, model.c_s
        self.J_t, self.J3 = model.J_t, model.J3
        self.wheel_bars = model.wheel_bars
        self.torque_wheels = model.torque_wheels
        self.speed_wheels = model.speed_wheels
        self.gyro_coef = model.J_a[self.wheel_bars] / model.l[self.wheel_bars]
        self.gyroscopic = "gyroscopic" in model.terms
        self.all_bars_wheeled = np.array_equal(self.wheel_bars, np.arange(self.beta))
        self.M_red_inv = np.linalg.inv(model.M_red.toarray())  # (m, m), symmetric
        self.U2 = model.U2.toarray()  # (n, m)
        # products with the constant matrices, so that no (3, n) node matrix is ever formed
        self.E_all = self.U2T @ np.hstack([self.C_b.T, self.C_s.T])  # (m, beta + alpha)
        self.Y0 = self.N_fixed @ np.hstack([self.C_b.T, self.C_s.T])  # (3, beta + alpha)
        self.W_Cb, self.Cs_Cb, self.Cb_Cb = (
            self.W @ self.C_b.T, self.C_s @ self.C_b.T, self.C_b @ self.C_b.T
        )  # fmt: skip
        self.W_U2, self.Cs_U2, self.Cb_U2 = (
            self.W @ self.U2, self.C_s @ self.U2, self.C_b @ self.U2
        )  # fmt: skip
        if self.c:
            self._multiplier_constants(model)

    def _multiplier_constants(self, model):
        """Dense form of the multiplier system (see ``Model._multiplier_system``)."""
        c = self.c
        M_s_inv = model.M_s_inv.toarray()
        P = model.structure.P.toarray()  # (n, c)
        self.W_MP, self.Cs_MP, self.Cb_MP = (
            self.W @ M_s_inv @ P, self.C_s @ M_s_inv @ P, self.C_b @ M_s_inv @ P
        )  # fmt: skip
        self.H = model.H.toarray()  # (beta, c) = C_b P
        rows, cols, vals = model.omega_const
        K0 = np.zeros((3 * c, 3 * c))
        np.add.at(K0, (rows, cols), vals)
        self.K0 = K0
        # coef_i (c, c) per bar: sum of -1/2 q_a h_b over the pairs of bar i
        coef = np.zeros((self.beta, c, c))
        r = model.omega_pairs_rows.reshape(-1, 9)[:, 0] // 3
        s = model.omega_pairs_cols.reshape(-1, 9)[:, 0] // 3
        np.add.at(coef, (model.omega_pairs_bar, r, s), model.omega_pairs_coef)
        self.coef_flat = coef.reshape(self.beta, c * c)

    # -- pieces --------------------------------------------------------------------------------
    def nodes(self, q, q_dot):
        """Node positions and velocities (K, 3, n) of reduced coordinates (K, 3, m)."""
        return self.N_fixed + q @ self.U2T, q_dot @ self.U2T

    def accelerations(self, q, q_dot, omega_w, rest):
        """Reduced accelerations and node accelerations of a batch of states.

        Parameters
        ----------
        q, q_dot : ndarray, shape (K, 3, m), m and m/s (real or complex)
        omega_w : ndarray, shape (K, n_w), rad/s
        rest : ndarray, shape (K, alpha) or (alpha,), m
            String rest lengths.

        Returns
        -------
        eta2_ddot : ndarray, shape (K, 3, m), m/s^2
        N_ddot : ndarray, shape (K, 3, n), m/s^2
        """
        beta = self.beta
        Y = q @ self.E_all + self.Y0  # bars and strings (K, 3, beta + alpha), never N itself
        Y_dot = q_dot @ self.E_all
        B, S = Y[:, :, :beta], Y[:, :, beta:]
        B_dot, S_dot = Y_dot[:, :, :beta], Y_dot[:, :, beta:]
        b2 = (B * B).sum(axis=1)  # (K, beta)
        # forces as columns: F = W - X_s C_s + X_b C_b (strings X_s, bars X_b), used only
        # through products with constant matrices
        X_s = self._string_forces(S, S_dot, rest)
        X_b = self._gyroscopic(B, B_dot, omega_w) if self.gyroscopic else np.zeros_like(B)
        FC = self.W_Cb - X_s @ self.Cs_Cb + X_b @ self.Cb_Cb  # F C_b^T
        lam = -(self.J_t * (B_dot * B_dot).sum(axis=1) + 0.5 * (B * FC).sum(axis=1)) / b2
        X_b = X_b + B * lam[:, None, :]
        if self.c:
            X_b = X_b + self._multiplier_forces(B, b2, X_s, X_b)
        f_red = self.W_U2 - X_s @ self.Cs_U2 + X_b @ self.Cb_U2  # (W_T - N K_s) U2
        eta2_ddot = f_red @ self.M_red_inv
        return eta2_ddot, eta2_ddot @ self.U2T

    def _string_forces(self, S, S_dot, rest):
        """S gamma^ (K, 3, alpha): tension-only strings with damping while taut."""
        s = np.sqrt((S * S).sum(axis=1))
        s_dot = (S * S_dot).sum(axis=1) / s
        tension = self.k_s * (s - rest) + self.c_s * s_dot
        taut = (s.real > rest) & (tension.real > 0.0)
        return S * np.where(taut, tension / s, 0.0)[:, None, :]

    def _gyroscopic(self, B, B_dot, omega_w):
        """Wheel term of W_T (Eq. 59): J_a omega_w b x b_dot / l per wheel bar, (K, 3, beta)."""
        i = self.wheel_bars
        b, d = (B, B_dot) if self.all_bars_wheeled else (B[:, :, i], B_dot[:, :, i])
        cross = np.stack(
            [
                b[:, 1] * d[:, 2] - b[:, 2] * d[:, 1],
                b[:, 2] * d[:, 0] - b[:, 0] * d[:, 2],
                b[:, 0] * d[:, 1] - b[:, 1] * d[:, 0],
            ],
            axis=1,
        )
        G = cross * (self.gyro_coef * omega_w)[:, None, :]
        if self.all_bars_wheeled:
            return G
        out = np.zeros_like(B)
        out[:, :, i] = G
        return out

    def _multiplier_forces(self, B, b2, X_s, X_b):
        """Bar-force columns added by the multipliers Omega (Eqs. 62, 67), shape (K, 3, beta).

        ``X_s, X_b`` are the string and bar force columns so far (F = W - X_s C_s + X_b C_b).
        """
        K, c = B.shape[0], self.c
        rhs = -(self.W_MP - X_s @ self.Cs_MP + X_b @ self.Cb_MP)  # -N_ddot_0 P, (K, 3, c)
        bb = (B[:, :, None, :] * (B / b2[:, None, :])[:, None, :, :]).reshape(K, 9, self.beta)
        # sum_i kron(coef_i, b_i b_i^T / |b_i|^2): (K, 9, c c) -> (K, c, 3, c, 3)
        pairs = (bb @ self.coef_flat).reshape(K, 3, 3, c, c).transpose(0, 3, 1, 4, 2)
        Kmat = pairs.reshape(K, 3 * c, 3 * c) + self.K0
        rhs_vec = np.swapaxes(rhs, 1, 2).reshape(K, 3 * c, 1)  # unknown index 3 j + r
        Omega = np.swapaxes(np.linalg.solve(Kmat, rhs_vec).reshape(K, c, 3), 1, 2)
        OH = Omega @ self.H.T  # (K, 3, beta)
        lam_Omega = -0.5 * (B * OH).sum(axis=1) / b2
        # Omega P^T itself is left out: it has no component in the reduced space (P^T U2 = 0)
        return B * lam_Omega[:, None, :]

    def wheel_acceleration(self, u, dtype=float):
        """Spin acceleration of every wheel (n_w,), rad/s^2: torque / J_3 for torque wheels."""
        out = np.zeros(len(self.wheel_bars), dtype=dtype)
        tq = self.torque_wheels
        if len(tq):
            out[tq] = u[self.alpha + tq] / self.J3[self.wheel_bars[tq]]
        return out


def check_model(model) -> None:
    """Raise :class:`EstimatorConfigError` for models the estimator does not support."""
    if model.beta == 0:
        raise EstimatorConfigError(f"scene {model.scene.name!r}: the estimator needs bars")
