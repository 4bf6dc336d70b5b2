"""Where a fixed step must stop: a string going taut.

A string pulls with ``k (s - s0) + c s_dot`` while it is longer than its rest length and never
pushes (:func:`.dynamics.string_force_densities`). One going taut lengthens (``s_dot > 0``), so
its damper pulls at once: the force jumps by ``c s_dot``. A fixed step across the jump errs by
the jump's force for up to a sixth of the step (RK4's stage weights as a quadrature of the jump:
the error's spread is ``h / 6``), where it resolves a smooth force to ``h^4``; a string going
slack has no jump (its force falls to zero before it is slack). :class:`.simulate.Stepper`
therefore ends a step where a string goes taut and steps on from there, each part under a
smooth force.
"""

import numpy as np

MAX_ITERATIONS = 30
"""Regula falsi iterations at most: the Illinois variant halves the bracket's far end's weight
each time it repeats, so it converges superlinearly; a bracket still open after this many is
closed at its taut end (the jump then lies within the bracket)."""
TOLERANCE = 1e-9
"""Width of the bracket on the crossing, as a share of the step, that ends the search."""


class Tautening:
    """The strings of ``model`` going taut: their stretches from the state by one dense product
    (every substep asks twice), and the share of a step where the first goes taut."""

    def __init__(self, model):
        st = model.structure
        ends = np.zeros((model.n, model.alpha))
        ends[st.string_end, np.arange(model.alpha)] += 1.0
        ends[st.string_start, np.arange(model.alpha)] -= 1.0
        # S = N ends, N = N_fixed + q U2^T (Model.nodes): S = S0 + q (U2^T ends)
        self._S0 = model.N_fixed_T.T @ ends
        self._Q = np.asarray(model.U2.T @ ends)
        self._q, self._shape = model.layout.q, (3, model.m)
        self.alpha = model.alpha
        self.damped = model.c_s > 0.0

    def stretches(self, x, u) -> np.ndarray:
        """Each string's length less its rest length in ``u`` (alpha,) m at the state ``x``."""
        S = x[self._q].reshape(self._shape) @ self._Q + self._S0
        return np.sqrt((S * S).sum(axis=0)) - u[: self.alpha]

    def between(self, start, end) -> bool:
        """Whether a damped string is slack at ``start`` and taut at ``end``, each a pair
        (state, input)."""
        if not self.damped.any():
            return False
        before, after = self.stretches(*start), self.stretches(*end)
        return bool(np.any(self.damped & (before <= 0.0) & (after > 0.0)))

    def share(self, start, at) -> float:
        """The share of a step from ``start`` (state, input) at which its first damped string
        goes taut, on the taut side: regula falsi (Illinois) on the largest stretch of the
        strings slack at the start, ``at(share)`` giving the state and the input that share of
        the step on."""
        before = self.stretches(*start)
        slack = self.damped & (before <= 0.0)

        def lead(share):
            return float(np.max(self.stretches(*at(share))[slack]))

        lo, hi, g_lo, g_hi, side = 0.0, 1.0, float(np.max(before[slack])), lead(1.0), 0
        for _ in range(MAX_ITERATIONS):
            if hi - lo <= TOLERANCE:
                break
            mid = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
            mid = min(max(mid, lo + 0.5 * TOLERANCE), hi - 0.5 * TOLERANCE)
            g = lead(mid)
            if g > 0.0:
                hi, g_hi = mid, g
                g_lo = g_lo / 2.0 if side == 1 else g_lo
                side = 1
            else:
                lo, g_lo = mid, g
                g_hi = g_hi / 2.0 if side == -1 else g_hi
                side = -1
        return hi
