"""Quasi-static shapes: where the nodes sit, in the body frame, for given rest lengths of the
actuated strings, and how they move when the rest lengths change.

The servos change rest lengths in seconds, the strings ring at tens of hertz: the planner treats
the shape as the static equilibrium of the current rest lengths (as :mod:`.reduced` does for the
D-bar). Two ways to find it:

- :class:`RhombusShape`: the D-bar's closed form (:class:`.reduced.DBarReduced`), one coordinate
  ``d``, the n1-n3 rest length; the n2-n4 string follows the rhombus (``sqrt(4 l^2 - d^2)``).
- :class:`StaticShape`: any free scene. The equilibrium is a stationary point of the strings'
  elastic energy ``V = sum k_i (L_i - r_i)^2 / 2`` (taut strings only) on the manifold of fixed
  bar lengths, found by Newton's method on the Lagrange conditions (an SQP step solves
  ``[K G^T; G 0] [dy; lambda] = -[grad V; c]``). Six gauge conditions fix the rigid motion the
  energy does not see: the centre of mass stays where it starts and the body frame keeps its
  start axes, so that the shape *is* the body-frame shape. ``ds/dr`` follows from the same
  matrix by the implicit function theorem (one solve per actuated string).

Both return positions in the *gauge*: the world axes are the body frame's start axes ``F0``,
so a quantity computed on them is read in body axes by ``F0^T``.
"""

import numpy as np

from gyrotensegrity import BodyFrame

from .errors import PlanError
from .reduced import DBarReduced, rhombus_range

NEWTON_STEPS = 40
NEWTON_TOL = 1e-12
"""Largest Newton step, relative to the largest bar length, at which the shape is taken as
converged (a few hundred times the round-off of the positions)."""
MAX_CONDITION = 1e12
"""Condition number of the Lagrange system beyond which the shape is no equilibrium the strings
hold (a mechanism: slack strings leave a motion that costs no energy)."""


def string_index(model, name):
    """Index of the scene string ``name`` in the model's input."""
    names = [s.name for s in model.scene.strings]
    if name not in names:
        raise PlanError(f"scene {model.scene.name}: no string {name} (it has {', '.join(names)})")
    return names.index(name)


class RhombusShape:
    """The D-bar's rhombus: one coordinate, the n1-n3 rest length ``d`` (m).

    Parameters
    ----------
    model : gyrotensegrity.Model
    limits : Limits
        Servo ranges and the smallest diagonal bound ``d`` (:func:`.reduced.rhombus_range`).
    """

    def __init__(self, model, limits):
        self.model = model
        self.dbar = DBarReduced(model)
        self.names = tuple(model.scene.strings[i].name for i in (self.dbar.i13, self.dbar.i24))
        lo, hi = rhombus_range(self.dbar, limits, self.names)
        self.lo, self.hi = np.array([lo]), np.array([hi])
        self.rest = np.array([self.dbar.d_rest])
        names = np.array(model.structure.node_names)
        self._along_x = np.isin(names, ["n1", "n3"])

    def rest_lengths(self, r):
        """Rest lengths (..., 2) m of the two strings for coordinates ``r`` (..., 1)."""
        d = r[..., 0]
        return np.stack([d, np.sqrt(4.0 * self.dbar.l**2 - d * d)], axis=-1)

    def solve(self, r, guess=None):
        """Positions (3, n) m and their derivative (1, 3, n) by ``d``; ``guess`` unused."""
        d = float(r[0])
        N = self.dbar.shape(d)
        centre = N[:, self._along_x].mean(axis=1)[:, None]
        h2 = 4.0 * self.dbar.l**2 - d * d
        # n1, n3 sit at -+d/2 along x, n2, n4 at +-h/2 along y with h = sqrt(4 l^2 - d^2)
        scale = np.where(self._along_x, 1.0 / d, -d / h2)
        return N, ((N - centre) * scale)[None]


class StaticShape:
    """Static equilibrium of any free scene for the rest lengths of its actuated strings.

    Parameters
    ----------
    model : gyrotensegrity.Model
    names : sequence of str
        The actuated strings (scene names); the coordinates are their rest lengths, m.
    limits : Limits
        Each string's servo range.
    travel_m : float, m
        How far from its rest length a string may go (the coordinates' box is the servo range
        cut to ``rest +- travel_m``).
    """

    def __init__(self, model, names, limits, travel_m):
        self.model, self.names = model, tuple(names)
        self.idx = np.array([string_index(model, n) for n in self.names], dtype=int)
        u0 = model.input_at(0.0)
        self.rest_all = u0[: model.alpha].copy()
        self.rest = self.rest_all[self.idx].copy()
        ranges = np.array([limits.range_of(n) for n in self.names]).reshape(-1, 2)
        self.lo = np.maximum(ranges[:, 0], self.rest - travel_m)
        self.hi = np.minimum(ranges[:, 1], self.rest + travel_m)
        bad = [n for n, a, r, b in zip(self.names, self.lo, self.rest, self.hi, strict=True)
               if not a <= r <= b]  # fmt: skip
        if bad:
            raise PlanError(f"limits leave the rest length of {', '.join(bad)} out of range")
        self._constants(model)

    def _constants(self, model):
        st, n = model.structure, model.structure.n
        self.C_s, self.C_b = st.C_s.toarray(), st.C_b.toarray()
        self.P = np.kron(np.eye(3), model.U2.toarray())  # vec(N) = vec(N_fixed) + P vec(q)
        mass = st.C_r.toarray().T @ model.m_t + model.m_node
        frame = BodyFrame.of_model(model)
        a, b, c, d = frame.cols
        rows, values = [], []
        for axis in range(3):  # centre of mass where it starts
            rows.append(np.kron(np.eye(3)[axis], mass / mass.sum()))
            values.append(float(rows[-1] @ st.N0.ravel()))
        for p, q, axis in ((a, b, 1), (a, b, 2), (c, d, 2)):  # the frame keeps its start axes
            row = np.zeros((3, n))
            row[:, q], row[:, p] = frame.F0[:, axis], -frame.F0[:, axis]
            rows.append(row.ravel())
            values.append(0.0)
        self.gauge, self.gauge_values = np.array(rows), np.array(values)
        self.scale = float(np.max(model.l))
        self.N0 = st.N0

    def rest_lengths(self, r):
        """Rest lengths (..., a) m of the actuated strings: the coordinates themselves."""
        return r

    def _terms(self, N, rest, lam):
        """Energy gradient (3n,), Hessian (3n, 3n), bar residuals (beta,) and their rows
        (beta, 3n) at positions ``N`` with bar multipliers ``lam``."""
        m, n = self.model, N.shape[1]
        S, B = N @ self.C_s.T, N @ self.C_b.T
        L = np.sqrt(np.sum(S * S, axis=0))
        taut = L > rest
        gamma = np.where(taut, m.k_s * (L - rest) / L, 0.0)
        grad = (S * gamma) @ self.C_s
        u = S / L
        ratio = np.where(taut, rest / L, 1.0)
        K_i = m.k_s[:, None, None] * (
            ratio[:, None, None] * np.einsum("di,ei->ide", u, u)
            + (1.0 - ratio)[:, None, None] * np.eye(3)
        )
        K_i = K_i * taut[:, None, None]
        hess = np.einsum("ide,ia,ib->daeb", K_i, self.C_s, self.C_s).reshape(3 * n, 3 * n)
        bars = np.einsum("j,ja,jb->ab", 2.0 * lam, self.C_b, self.C_b)
        hess += np.kron(np.eye(3), bars)
        residual = np.sum(B * B, axis=0) - m.l**2
        rows = np.einsum("dj,ja->jda", 2.0 * B, self.C_b).reshape(len(m.l), 3 * n)
        return grad.ravel(), hess, residual, rows

    def _system(self, N, rest, lam):
        grad, hess, residual, rows = self._terms(N, rest, lam)
        G = np.vstack([rows, self.gauge]) @ self.P
        c = np.concatenate([residual, self.gauge @ N.ravel() - self.gauge_values])
        k = G.shape[0]
        kkt = np.block([[self.P.T @ hess @ self.P, G.T], [G, np.zeros((k, k))]])
        if np.linalg.cond(kkt) > MAX_CONDITION:
            raise PlanError(
                f"scene {self.model.scene.name}: {self._where(rest[self.idx])} its strings hold "
                "no shape (slack strings or too few of them leave it a mechanism)"
            )
        return kkt, np.concatenate([self.P.T @ grad, c])

    def solve(self, r, guess=None):
        """Positions (3, n) m of the equilibrium at coordinates ``r`` (a,) m and their
        derivative (a, 3, n) by ``r``; Newton from ``guess`` (default the scene's start)."""
        rest = self.rest_all.copy()
        rest[self.idx] = r
        N = self.N0 if guess is None else guess
        lam = np.zeros(self.model.beta)
        for _ in range(NEWTON_STEPS):
            kkt, rhs = self._system(N, rest, lam)
            step = np.linalg.solve(kkt, -rhs)  # new multipliers, not their increments
            dy, lam = step[: self.P.shape[1]], step[self.P.shape[1] : self.P.shape[1] + len(lam)]
            N = N + (self.P @ dy).reshape(N.shape)
            if np.max(np.abs(dy)) < NEWTON_TOL * self.scale:
                return N, self._tangent(N, rest, lam)
        raise PlanError(
            f"scene {self.model.scene.name}: {self._where(r)} Newton's method finds no equilibrium"
        )

    def _where(self, r):
        """``at rest lengths ... m of s7, s8,`` (or ``at its rest lengths,``) for messages."""
        if not len(self.idx):
            return "at its rest lengths,"
        return (
            f"at rest lengths {np.round(np.asarray(r), 4).tolist()} m of {', '.join(self.names)},"
        )

    def _tangent(self, N, rest, lam):
        """``dN/dr`` (a, 3, n) at the equilibrium ``N`` (implicit function theorem)."""
        if not len(self.idx):
            return np.zeros((0, *N.shape))
        kkt, _ = self._system(N, rest, lam)
        S = N @ self.C_s.T
        L = np.sqrt(np.sum(S * S, axis=0))
        cols, n_y = [], self.P.shape[1]
        for i in self.idx:  # d grad / d r_i = -k_i S_i / L_i at its two nodes (taut)
            d_grad = -(self.model.k_s[i] / L[i]) * np.outer(S[:, i], self.C_s[i]) * (L[i] > rest[i])
            cols.append(np.concatenate([self.P.T @ d_grad.ravel(), np.zeros(len(kkt) - n_y)]))
        dy = np.linalg.solve(kkt, -np.column_stack(cols))[:n_y]
        return np.stack([(self.P @ dy[:, j]).reshape(N.shape) for j in range(len(self.idx))])
