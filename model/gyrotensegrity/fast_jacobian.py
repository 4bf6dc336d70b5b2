"""Closed-form Jacobian of the fast path's accelerations with respect to the state.

For :class:`gyrotensegrity.fast.FastDynamics` on its dense path without joint multipliers
(reduced coordinates; full coordinates of structures without joints), the accelerations
``z_ddot(q, q_dot, omega_w, rest)`` (3, m') m/s^2 and their derivatives with respect to every
entry of the coordinates ``q`` (3, m') m, their rates ``q_dot`` (3, m') m/s, the wheel spins
``omega_w`` (n_w,) rad/s and the string rest lengths ``rest`` (alpha,) m, by the chain rule
through the formulation of :mod:`.fast` (docs/model.md#closed-form-jacobian-of-the-fast-path);
the compiled kernel holds the same formulas in C::

    z_ddot = f0 M^-1 + (B mu^) E M^-1,     f0 = W U + G E - F E_s,
    mu = Z^-1 r,  Z = Y .* (B^T B),        r_j = -|b_dot_j|^2 - b_j . (f0 M^-1 E^T)_j

with bars ``B = B_fix + q E^T``, strings ``S = S_fix + q E_s^T``. The pieces:

- string i (taut: ``s > rest`` and tension ``t = k (s - rest) + c s_dot > 0``; slack: 0),
  force ``F_i = (t / s) S_i``, ``u = S_i / s``: the tangent stiffness
  ``dF/dS = (t/s)(I - u u^T) + k u u^T + (c/s) u (S_dot - s_dot u)^T``, the damping
  ``dF/dS_dot = c u u^T``, ``dF/d rest = -k u``;
- gyroscopic column of a wheel bar ``G_i = phi_i b_i x b_dot_i``, ``phi_i = J_a omega_w / l``:
  ``dG/db = -phi [b_dot]_x``, ``dG/db_dot = phi [b]_x``, ``dG/d omega_w = (J_a / l) b x b_dot``;
- bar multipliers: ``d mu = Z^-1 (dr - dZ mu)``, ``(dZ mu)_j = db_j . p_j + b_j . sum_k Y_jk
  mu_k db_k`` with ``p_j = sum_k Y_jk mu_k b_k``.

Units: Jacobian entries are (m/s^2) per unit of the state entry: 1/s^2 (positions), 1/s
(velocities), m/(s rad) (wheel spins), 1/s^2 (rest lengths).
"""

import numpy as np

from .errors import SceneError


class JacobianUnsupported(SceneError):
    """The closed-form Jacobian does not cover this fast-path variant (sparse or joints)."""


def check_supported(dyn) -> None:
    """Raise :class:`JacobianUnsupported` unless ``dyn`` is on the dense path without joints."""
    if not dyn.EE_T.dense or dyn.c_u or dyn.sparse is not None:
        raise JacobianUnsupported(
            f"scene {dyn.model.scene.name!r}: the closed-form Jacobian needs the fast path's "
            "dense variant without joint multipliers (reduced coordinates, at most "
            "fast.DENSE_LIMIT of them); use the complex step"
        )


def _cross(a, b):
    """Column-wise cross product of (3, k) arrays."""
    return np.stack(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def outer_rows(V, E):
    """``out[j, b m' + l] = V[b, j] E[j, l]``: a member quantity along the coordinates its
    vector moves with; V (3, k), E (k, m') -> (k, 3 m')."""
    return (V.T[:, :, None] * E[:, None, :]).reshape(E.shape[0], -1)


def string_tangents(S, S_dot, rest, k_s, c_s):
    """Force columns of the strings and their derivatives.

    Parameters
    ----------
    S, S_dot : ndarray, shape (3, alpha), m and m/s
        String vectors and their rates.
    rest : ndarray, shape (alpha,), m
    k_s, c_s : ndarray, shape (alpha,), N/m and N s/m

    Returns
    -------
    F : ndarray, shape (3, alpha), N
        Force of each string on its end node (``gamma S``; zero when slack).
    dF_dS, dF_dS_dot : ndarray, shape (alpha, 3, 3), N/m and N s/m
    dF_drest : ndarray, shape (3, alpha), N/m
    """
    s = np.sqrt((S * S).sum(axis=0))
    u = S / s
    s_dot = (u * S_dot).sum(axis=0)
    t = k_s * (s - rest) + c_s * s_dot
    taut = (s > rest) & (t > 0.0)
    gain = np.where(taut, 1.0, 0.0)
    uT = u.T
    uu = uT[:, :, None] * uT[:, None, :]
    eye = np.eye(3)[None]
    rate = (S_dot - s_dot * u) * (c_s / s)
    dF_dS = (t / s)[:, None, None] * (eye - uu) + k_s[:, None, None] * uu
    dF_dS = (dF_dS + uT[:, :, None] * rate.T[:, None, :]) * gain[:, None, None]
    dF_dS_dot = (c_s * gain)[:, None, None] * uu
    return u * (t * gain), dF_dS, dF_dS_dot, -k_s * gain * u


_ROWS, _COLS = np.array([2, 0, 1]), np.array([1, 2, 0])  # [v]_x: +v at these, -v transposed


class FastJacobian:
    """Closed-form Jacobian of a :class:`gyrotensegrity.fast.FastDynamics`' accelerations.

    Parameters
    ----------
    dyn : gyrotensegrity.fast.FastDynamics
        On its dense path without joints (:func:`check_supported`).
    kernel : bool
        Evaluate in the compiled kernel (``_fastkernel.jacobian``, the same formulas in C)
        when ``dyn`` uses it; else, and as its reference, in numpy.
    """

    def __init__(self, dyn, kernel: bool = True):
        check_supported(dyn)
        self.dyn = dyn
        n, beta, alpha, nw = dyn.size, dyn.beta, dyn.alpha, dyn.n_wheels
        self.n, self.beta, self.alpha, self.nw = n, beta, alpha, nw
        self.size = 6 * n + nw + alpha  # columns: q, q_dot, omega_w, rest
        self.EE_T = dyn.EE_T.A  # (m', beta + alpha): bars then strings
        self.EE = np.ascontiguousarray(self.EE_T.T)
        self.E, self.Es = self.EE[:beta], self.EE[beta:]
        self.Minv_both = np.hstack([dyn.Minv.A, dyn.Minv_ET.A])  # (m', m' + beta)
        self.E_Minv = dyn.E_Minv.A
        self.k_s = np.broadcast_to(dyn.k_s, (alpha,)).astype(float)
        self.c_s = np.broadcast_to(dyn.c_s, (alpha,)).astype(float)
        wb = dyn.wheel_bars
        self.wheel_bars, self.gyro_coef, self.E_wheels_T = wb, dyn.gyro_coef, self.E[wb].T
        self.kernel = dyn.kernel if kernel else None
        if self.kernel is not None:
            self._work = np.empty(self.kernel.jacobian_work(dyn._dims))

    def __call__(self, q, q_dot, omega_w, rest):
        """Accelerations and their Jacobian at one real state.

        Parameters
        ----------
        q, q_dot : ndarray, shape (3, m'), m and m/s
        omega_w : ndarray, shape (n_w,), rad/s
            Spin of every wheel (speed wheels included: the derivative is with respect to it).
        rest : ndarray, shape (alpha,), m
            Rest lengths the string forces see.

        Returns
        -------
        z_ddot : ndarray, shape (3, m'), m/s^2
        J : ndarray, shape (3 m', 6 m' + n_w + alpha)
            ``d vec(z_ddot) / d [vec(q), vec(q_dot), omega_w, rest]`` (vec row by row, as the
            state vectors of :mod:`.fast`).
        """
        self.dyn.check_spins(omega_w)
        if self.kernel is not None:
            return self._compiled(q, q_dot, omega_w, rest)
        return self._numpy(q, q_dot, omega_w, rest)

    def _compiled(self, q, q_dot, omega_w, rest):
        dyn = self.dyn
        state = np.concatenate([np.ravel(q), np.ravel(q_dot), omega_w, rest]).astype(float)
        z_ddot = np.empty((3, self.n))
        J = np.empty((3 * self.n, self.size))
        status = self.kernel.jacobian(dyn._consts, dyn._dims, state, z_ddot, J, self._work)
        if status:
            dyn._singular(float("nan"), status - 1)
        return z_ddot, J

    def _numpy(self, q, q_dot, omega_w, rest):
        n, beta, dyn = self.n, self.beta, self.dyn
        pos, vel = q @ self.EE_T + dyn.off, q_dot @ self.EE_T
        B, B_dot, S, S_dot = pos[:, :beta], vel[:, :beta], pos[:, beta:], vel[:, beta:]
        F, dF_dS, dF_dSd, dF_dr = string_tangents(S, S_dot, rest, self.k_s, self.c_s)
        phi = np.zeros(beta)
        phi[self.wheel_bars] = self.gyro_coef * omega_w
        BxBd = _cross(B, B_dot)
        f0 = dyn.WU + (BxBd * phi) @ self.E - F @ self.Es
        Jf = self._force_jacobian(B, B_dot, phi, BxBd, dF_dS, dF_dSd, dF_dr)

        # unconstrained accelerations a0 = f0 M^-1 and V = f0 M^-1 E^T, with their derivatives
        a0V = f0 @ self.Minv_both
        Ja0V = self.Minv_both.T @ Jf  # (3, m' + beta, D)
        a0, V, Ja0, JV = a0V[:, :n], a0V[:, n:], Ja0V[:, :n], Ja0V[:, n:]
        r = -(B_dot * B_dot).sum(axis=0) - (B * V).sum(axis=0)
        Jr = -(B[:, :, None] * JV).sum(axis=0)
        Jr[:, 3 * n : 6 * n] -= 2.0 * outer_rows(B_dot, self.E)

        Y = dyn.Y
        Z_inv = np.linalg.inv(Y * (B.T @ B))
        mu = Z_inv @ r
        Ymu = Y * mu
        # through the bars in r and in Z (p_j = sum_k Y_jk mu_k b_k)
        Jr[:, : 3 * n] -= outer_rows(V + B @ Ymu.T, self.E) + outer_rows(B, Ymu @ self.E)
        Jmu = Z_inv @ Jr

        z_ddot = a0 + (B * mu) @ self.E_Minv
        J = Ja0 + (B[:, :, None] * self.E_Minv).transpose(0, 2, 1) @ Jmu
        C = self.E_Minv.T @ (self.E * mu[:, None])  # d(B mu^ E M^-1)/dB through B alone
        for a in range(3):
            J[a, :, a * n : (a + 1) * n] += C
        return z_ddot, J.reshape(3 * n, self.size)

    def _force_jacobian(self, B, B_dot, phi, BxBd, dF_dS, dF_dSd, dF_dr):
        """``d f0 / d x`` (3, m', D): per member a 3x6 block over (its vector, its rate),
        spread over the coordinates by its row of ``[E; E_s]``; wheel and rest columns."""
        n, beta, nw = self.n, self.beta, self.nw
        blocks = np.zeros((beta + self.alpha, 3, 6))
        blocks[:beta, _ROWS, _COLS] = -(phi * B_dot).T  # -phi [b_dot]_x
        blocks[:beta, _COLS, _ROWS] = (phi * B_dot).T
        blocks[:beta, _ROWS, _COLS + 3] = (phi * B).T  # phi [b]_x
        blocks[:beta, _COLS, _ROWS + 3] = -(phi * B).T
        blocks[beta:, :, :3] = -dF_dS
        blocks[beta:, :, 3:] = -dF_dSd
        Jf = np.empty((3, n, self.size))
        spread = (blocks.reshape(-1, 18, 1) * self.EE[:, None, :]).reshape(-1, 18 * n)
        Jf[:, :, : 6 * n] = (self.EE_T @ spread).reshape(n, 3, 6 * n).transpose(1, 0, 2)
        wheels = BxBd[:, self.wheel_bars] * self.gyro_coef
        Jf[:, :, 6 * n : 6 * n + nw] = wheels[:, None, :] * self.E_wheels_T
        Jf[:, :, 6 * n + nw :] = -dF_dr[:, None, :] * self.Es.T
        return Jf
