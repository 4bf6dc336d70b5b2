"""The constraint manifold's projections (:class:`.manifold.Manifold`) in the model's compiled
kernel (``gyrotensegrity._fastkernel.manifold``): the same Gauss-Newton steps and projector,
each a few dozen numpy calls in Python, in one call. The Gram matrices ``G G^T`` are factored
by Cholesky where the reference solves by LU, and ``Pi P Pi^T`` is formed as ``Pi P - (Pi P
Y^T) G`` (``Y = (G G^T)^-1 G``) rather than from ``Pi``: equal to round-off
(tests/estimator/test_fast_manifold.py). Where the kernel finds a Gram matrix singular the
reference takes the call."""

import numpy as np

from gyrotensegrity.fast import _fastkernel

from .manifold import Manifold


def fast_manifold(model, layout):
    """A :class:`FastManifold` of ``model``'s bars in the filter state ``layout``, or None
    without the compiled kernel."""
    return None if _fastkernel is None else FastManifold(model, layout)


class FastManifold(Manifold):
    """:class:`.manifold.Manifold` with its projections in the compiled kernel."""

    def __init__(self, model, layout):
        super().__init__(model, layout)
        self._bars = [np.ascontiguousarray(a, float) for a in (self.E, self.B0, self.l2)]
        self.packed_bars = np.concatenate([a.ravel() for a in self._bars])
        """E (beta x m), B0 (3 x beta) and l2 (beta) one after the other (the kernel's one-call
        IMU cycle reads them so)."""
        self._work = np.empty(_fastkernel.manifold_work(layout.m, self.beta, layout.size))
        self._none = np.empty(0)

    def _call(self, x, P, rtol, iterations):
        x = np.array(x, float)
        P_out = self._none if P is None else np.empty((x.size, x.size))
        P = self._none if P is None else np.ascontiguousarray(P, float)
        spec = np.array([rtol, iterations], float)
        status = _fastkernel.manifold(*self._bars, spec, P, x, P_out, self._work)
        return (None, None) if status else (x, P_out)

    def project_state(self, x, rtol=1e-15, iterations=8):
        projected, _ = self._call(x, None, rtol, iterations)
        return super().project_state(x, rtol, iterations) if projected is None else projected

    def condition(self, x, P):
        projected, P_out = self._call(x, P, 1e-15, 8)
        return super().condition(x, P) if projected is None else (projected, P_out)
