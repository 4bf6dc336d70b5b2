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
closed at its taut end (the jump then lies within the bracket, 1e-9 of the step)."""
TOLERANCE = 1e-9
"""Width of the bracket on the crossing, as a share of the step, that ends the search."""


def stretches(model, x, u) -> np.ndarray:
    """Each string's length less its rest length in ``u`` (alpha,) m at the state ``x``."""
    st = model.structure
    N, _ = model.nodes(x)
    S = N[:, st.string_end] - N[:, st.string_start]
    return np.linalg.norm(S, axis=0) - u[: model.alpha]


def tautening(model, start, end) -> bool:
    """Whether a damped string is slack at ``start`` and taut at ``end``, each a pair (state,
    input)."""
    damped = model.c_s > 0.0
    if not damped.any():
        return False
    before, after = stretches(model, *start)[damped], stretches(model, *end)[damped]
    return bool(np.any((before <= 0.0) & (after > 0.0)))


def taut_fraction(model, start, at) -> float:
    """The share of a step from ``start`` (state, input) at which its first damped string goes
    taut, on the taut side: regula falsi (Illinois) on the largest stretch of the strings slack
    at the start, ``at(share)`` giving the state and the input that share of the step on."""
    x0, u0 = start
    damped = model.c_s > 0.0
    slack = damped & (stretches(model, x0, u0) <= 0.0)

    def lead(share):
        return float(np.max(stretches(model, *at(share))[slack]))

    lo, hi, g_lo, g_hi, side = 0.0, 1.0, lead(0.0), lead(1.0), 0
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
