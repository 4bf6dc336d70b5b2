"""The momentum terms of the quasi-static shapes, tabulated over the actuated rest lengths and
interpolated by a cubic that a complex step passes through.

For each grid point ``r`` of the coordinates' box the shape ``N(r)`` and ``dN/dr`` (:mod:`.shape`,
body-frame gauge) give, in body axes about the centre of mass:

- ``I_b`` (3, 3) kg m^2, the locked inertia tensor;
- ``h_b`` (3, n_w) kg m^2, each wheel's momentum per rad/s of spin;
- ``B_b`` (3, a) kg m^2/m, the momentum of the shape change per m/s of each rest length (the
  shape connection, ``A(s) ds/dr``; zero for the D-bar's symmetric change, not in general);
- ``L`` (alpha,) m, every string's length (the strings' tension for the taut constraint).

Between grid points a tensor-product Catmull-Rom cubic (C1, local: 4 points per axis; edges
extended linearly) interpolates them. Its weights are polynomials of the fractional position,
so complex coordinates give exact complex-step derivatives; its error is O(h^3) in the grid
step ``h`` (:func:`interpolation_error` measures it against direct solves).
"""

import itertools

import numpy as np

from gyrotensegrity import diagnostics

from .attitude_model import centre_of_mass, momentum_map
from .errors import PlanError

SHRINK = 0.8
"""Factor by which the coordinates' box shrinks towards the rest lengths while a corner has no
shape the strings hold (slack strings), up to :data:`SHRINK_TRIES` times."""
SHRINK_TRIES = 12


def momentum_terms(model, F0, N, dN):
    """``[vec(I_b) (9) | vec(h_b) (3 n_w) | vec(B_b) (3 a) | L (alpha)]`` of the shape ``N``
    (3, n) m with ``dN`` (a, 3, n) m/m, positions in the gauge of the body frame ``F0``."""
    centre = centre_of_mass(model, N)
    inertia, wheels = momentum_map(model, N)
    zero = np.zeros(len(model.wheel_bars))
    connection = [
        diagnostics.angular_momentum(
            model, N - centre[:, None], d - centre_of_mass(model, d)[:, None], zero
        )
        for d in dN
    ]
    connection = np.column_stack(connection) if connection else np.zeros((3, 0))
    S = N @ model.structure.C_s.T.toarray()
    lengths = np.sqrt(np.sum(S * S, axis=0))
    parts = (F0.T @ inertia @ F0, F0.T @ wheels, F0.T @ connection)
    return np.concatenate([p.ravel() for p in parts] + [lengths])


def _catmull_rom(t):
    """Weights (..., 4) of the points at -1, 0, 1, 2 for the fraction ``t`` (...) in [0, 1]."""
    t2, t3 = t * t, t * t * t
    return np.stack(
        [
            (-t3 + 2 * t2 - t) / 2,
            (3 * t3 - 5 * t2 + 2) / 2,
            (-3 * t3 + 4 * t2 + t) / 2,
            (t3 - t2) / 2,
        ],
        axis=-1,
    )


class ShapeTable:
    """The tabulated momentum terms of a shape provider (:mod:`.shape`).

    Parameters
    ----------
    model : gyrotensegrity.Model
    shape : RhombusShape or StaticShape
        Provides ``lo``, ``hi``, ``rest`` (a,) m and ``solve(r, guess)``.
    points : int
        Grid points per coordinate.
    F0 : ndarray, shape (3, 3)
        The body frame's start axes (the shapes' gauge).
    """

    def __init__(self, model, shape, points, F0):
        self.model, self.shape, self.points = model, shape, int(points)
        self.n_w, self.a, self.alpha = len(model.wheel_bars), len(shape.rest), model.alpha
        self.lo, self.hi = self._box(shape)
        self.axes = [np.linspace(a, b, self.points) for a, b in zip(self.lo, self.hi, strict=True)]
        self.step = (self.hi - self.lo) / (self.points - 1)
        self.values = self._tabulate(F0)
        self.F0 = F0

    def _box(self, shape):
        """The coordinates' box: the shape's, shrunk towards the rest lengths until every
        corner has a shape the strings hold."""
        lo, hi = np.array(shape.lo, float), np.array(shape.hi, float)
        shape.solve(shape.rest)  # no shape at the start: its error, not a box's
        for _ in range(SHRINK_TRIES):
            try:
                for corner in itertools.product(*zip(lo, hi, strict=True)):
                    shape.solve(np.array(corner))
                return lo, hi
            except PlanError:
                lo = shape.rest + SHRINK * (lo - shape.rest)
                hi = shape.rest + SHRINK * (hi - shape.rest)
        raise PlanError(f"no box of rest lengths around {shape.rest} m holds a shape")

    def _tabulate(self, F0):
        grid = np.array(list(itertools.product(*self.axes)), float)  # (points^a, a)
        N, rows = None, []
        for r in grid:  # neighbours in C order: each solve starts from the last shape
            N, dN = self.shape.solve(r, N)
            rows.append(momentum_terms(self.model, F0, N, dN))
        values = np.array(rows).reshape(*[self.points] * self.a, -1)
        for axis in range(self.a):  # one ghost point at each end, linear extension
            first = 2 * np.take(values, [0], axis) - np.take(values, [1], axis)
            last = 2 * np.take(values, [-1], axis) - np.take(values, [-2], axis)
            values = np.concatenate([first, values, last], axis=axis)
        return values

    def __call__(self, r):
        """The interpolated terms (..., nv) at coordinates ``r`` (..., a), real or complex."""
        r = np.asarray(r)
        if not self.a:  # one shape: the terms are constants
            return np.broadcast_to(self.values, r.shape[:-1] + self.values.shape)
        lead, a = r.shape[:-1], self.a
        index, weights = [], np.ones(lead + (1,), dtype=r.dtype)
        for k in range(a):
            u = (r[..., k] - self.lo[k]) / self.step[k]
            i = np.clip(np.floor(np.real(u)).astype(int), 0, self.points - 2)
            shape = lead + (1,) * k + (4,) + (1,) * (a - k - 1)
            index.append(i.reshape(lead + (1,) * a) + np.arange(4).reshape(shape[len(lead) :]))
            w = _catmull_rom(u - i)  # (..., 4): the weight tensor grows by this axis
            weights = (weights[..., :, None] * w[..., None, :]).reshape(lead + (-1,))
        block = self.values[tuple(index)].reshape(lead + (4**a, -1))
        return (weights[..., None, :] @ block)[..., 0, :]

    def split(self, values):
        """``(I_b (..., 3, 3), h_b (..., 3, n_w), B_b (..., 3, a), L (..., alpha))``."""
        lead = values.shape[:-1]
        sizes = np.cumsum([9, 3 * self.n_w, 3 * self.a])
        I_b, h_b, B_b, L = np.split(values, sizes, axis=-1)
        return (
            I_b.reshape(*lead, 3, 3),
            h_b.reshape(*lead, 3, self.n_w),
            B_b.reshape(*lead, 3, self.a),
            L,
        )

    def interpolation_error(self, samples=20, seed=0):
        """Largest relative error of the interpolated ``I_b``, ``h_b`` and ``B_b`` against direct
        solves at ``samples`` points of the box (midpoints of the grid's cells and random ones),
        each relative to that term's largest tabulated value."""
        rng = np.random.default_rng(seed)
        mids = [self.lo + (np.arange(self.a) * 0 + 0.5) * self.step]
        points = mids + list(self.lo + rng.random((samples, self.a)) * (self.hi - self.lo))
        worst = 0.0
        core = self.values[tuple([slice(1, -1)] * self.a)]
        for r in points:
            N, dN = self.shape.solve(np.asarray(r), None)
            exact = self.split(momentum_terms(self.model, self.F0, N, dN))
            got = self.split(self(np.asarray(r)))
            scales = self.split(np.max(np.abs(core.reshape(-1, core.shape[-1])), axis=0))
            for e, g, s in zip(exact[:3], got[:3], scales[:3], strict=True):
                if e.size:
                    worst = max(worst, float(np.max(np.abs(e - g)) / max(np.max(s), 1e-300)))
        return worst
