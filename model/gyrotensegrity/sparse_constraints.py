"""Constraint forces of large reduced-order structures with joints (the fast path's sparse
saddle-point solve, used by :class:`gyrotensegrity.fast.FastDynamics`)."""

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.linalg import solve_banded
from scipy.sparse.csgraph import reverse_cuthill_mckee


class SparseConstraints:
    """Large reduced-order structures with joints: ``E M^-1 E^T`` is dense, so the bar
    multipliers come from the sparse saddle-point system ``[[kron(I3, M), G^T], [G, 0]]``
    with the bar rows ``G[i, (r, k)] = b_ir E_ik``. Its pattern is fixed: a reverse
    Cuthill-McKee order computed once makes it banded for chain-like structures (bandwidth 8
    for prism chains), solved by banded LU in linear time; wider bands use sparse LU.
    Single states; batches are looped."""

    BAND_LIMIT = 64

    def __init__(self, M, E):
        Ec = sp.csr_matrix(E).tocoo()
        m, beta = M.shape[0], E.shape[0]
        n3, r = 3 * m, np.arange(3)
        self.m, self.size = m, n3 + beta
        self.g_rows = np.repeat(Ec.row, 3)
        self.g_cols = (r[None, :] * m + Ec.col[:, None]).ravel()  # coordinate (r, k) -> r m + k
        self.g_e = np.repeat(Ec.data, 3)
        self.g_r = np.tile(r, len(Ec.data))
        Mc = sp.kron(sp.identity(3), M).tocoo()
        self.m_rows, self.m_cols, self.m_vals = Mc.row, Mc.col, Mc.data
        rows = np.concatenate([Mc.row, n3 + self.g_rows, self.g_cols])
        cols = np.concatenate([Mc.col, self.g_cols, n3 + self.g_rows])
        pattern = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(self.size,) * 2)
        self.perm = reverse_cuthill_mckee(pattern, symmetric_mode=True)
        where = np.empty(self.size, dtype=int)
        where[self.perm] = np.arange(self.size)
        i, j = where[rows], where[cols]
        self.band = int(np.abs(i - j).max())
        if self.band <= self.BAND_LIMIT:
            w = self.band
            self.ab_const = np.zeros((2 * w + 1, self.size))
            nm = len(Mc.row)
            np.add.at(self.ab_const, (w + i[:nm] - j[:nm], j[:nm]), Mc.data)
            self.g_pos = (w + i[nm:] - j[nm:], j[nm:])

    def solve(self, f0, B, b2, bd2):
        """Accelerations (..., 3, m) from the reduced forces f0 without bar forces."""
        if B.ndim != 2:
            flat = [self.solve(f0[k], B[k], b2[k], bd2[k]) for k in np.ndindex(B.shape[:-2])]
            return np.reshape(flat, f0.shape)
        n3 = 3 * self.m
        g = B[self.g_r, self.g_rows] * self.g_e
        rhs = np.concatenate([f0.ravel(), -bd2])
        if self.band <= self.BAND_LIMIT:
            ab = self.ab_const.copy()
            ab[self.g_pos] = np.concatenate([g, g])
            w = self.band
            sol = np.empty(self.size)
            sol[self.perm] = solve_banded((w, w), ab, rhs[self.perm], check_finite=False)
        else:
            rows = np.concatenate([self.m_rows, n3 + self.g_rows, self.g_cols])
            cols = np.concatenate([self.m_cols, self.g_cols, n3 + self.g_rows])
            vals = np.concatenate([self.m_vals, g, g])
            K = sp.csc_matrix((vals, (rows, cols)), shape=(self.size, self.size))
            sol = spla.spsolve(K, rhs)
        return sol[:n3].reshape(3, self.m)
