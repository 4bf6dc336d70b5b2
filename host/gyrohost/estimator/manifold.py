"""The constraint manifold of the filter state and projections onto it.

Joints hold by construction (reduced coordinates ``eta2``, Eq. 64). The remaining constraints
are the bar lengths and their rates (Eq. 20)::

    g_pos,i = |b_i|^2 - l_i^2 = 0,     g_vel,i = b_i . b_i_dot = 0,     i = 1..beta

with ``B = const + eta2 E^T`` (``E = C_b U2``). The state is moved onto the manifold by
minimum-norm Gauss-Newton steps on ``eta2`` then ``eta2_dot`` -- the same corrections as
:func:`gyrotensegrity.projection.project` (a test compares them), dense for speed. The
covariance is projected onto the tangent space of the manifold with the linearised projector.
"""

import numpy as np

from .layout import layout_of


class Manifold:
    """Constraints of a model's bars in the filter state.

    Parameters
    ----------
    model : gyrotensegrity.Model
    layout : FilterLayout, optional
        The filter state's layout (default: the model's, without wheel noise states).
    """

    def __init__(self, model, layout=None):
        st = model.structure
        self.layout = layout_of(model) if layout is None else layout
        self.E = (st.C_b @ model.U2).toarray()  # (beta, m)
        self.B0 = np.asarray(model.N_fixed_T).T @ st.C_b.toarray().T  # (3, beta)
        self.l2 = model.l**2
        self.beta = model.beta

    def bars(self, x):
        """Bars and their rates (3, beta), m and m/s."""
        L = self.layout
        q = x[L.q].reshape(3, L.m)
        q_dot = x[L.q_dot].reshape(3, L.m)
        return self.B0 + q @ self.E.T, q_dot @ self.E.T

    def residual(self, x):
        """Constraint values (2 beta,): |b|^2 - l^2 (m^2), then b . b_dot (m^2/s)."""
        B, B_dot = self.bars(x)
        return np.concatenate([np.sum(B * B, axis=0) - self.l2, np.sum(B * B_dot, axis=0)])

    def jacobian(self, x):
        """d residual / dx, shape (2 beta, n)."""
        L = self.layout
        B, B_dot = self.bars(x)
        G = np.zeros((2 * self.beta, L.size))
        dB = self._d(B)
        G[: self.beta, L.q] = 2.0 * dB
        G[self.beta :, L.q] = self._d(B_dot)
        G[self.beta :, L.q_dot] = dB
        return G

    def _d(self, B):
        """d(b_i . v)/d eta2 for fixed v = B[:, i]: rows (beta, 3 m)."""
        return (B.T[:, :, None] * self.E[:, None, :]).reshape(self.beta, -1)

    def project_state(self, x, rtol=1e-15, iterations=8):
        """Minimum-norm projection of positions, then velocities, onto the constraints."""
        L = self.layout
        x = x.copy()
        q = x[L.q]
        for _ in range(iterations):
            B, _ = self.bars(x)
            g = np.sum(B * B, axis=0) - self.l2
            if np.max(np.abs(g) / self.l2) <= rtol:
                break
            Gp = 2.0 * self._d(B)
            q = q - Gp.T @ np.linalg.solve(Gp @ Gp.T, g)
            x[L.q] = q
        B, B_dot = self.bars(x)
        G = self._d(B)
        x[L.q_dot] = x[L.q_dot] - G.T @ np.linalg.solve(G @ G.T, np.sum(B * B_dot, axis=0))
        return x

    def condition(self, x, P):
        """Estimate and covariance moved onto the constraint manifold.

        The estimate by :meth:`project_state`; the covariance by the orthogonal projector onto
        the tangent space there, ``Pi = I - G^T (G G^T)^-1 G`` (``P <- Pi P Pi^T``), the
        linearisation of the same minimum-norm projection. (Conditioning on ``g = 0`` as on a
        perfect measurement, ``P - P G^T (G P G^T)^-1 G P``, divides by the nearly singular
        ``G P G^T`` of an already projected covariance and lost positive definiteness.)

        Returns
        -------
        x : ndarray, shape (n,), on the manifold
        P : ndarray, shape (n, n), symmetric, rank n - 2 beta
        """
        x = self.project_state(x)
        G = self.jacobian(x)
        Pi = np.eye(len(x)) - G.T @ np.linalg.solve(G @ G.T, G)
        P = Pi @ P @ Pi.T
        return x, 0.5 * (P + P.T)
