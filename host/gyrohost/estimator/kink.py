"""A tension-only string under a rest-length jitter: the mean of its rectified force and the
mean square of its error, in units of the jitter's std (the process model's ``kink_model =
"mean"`` and its jitter noise, docs/estimator.md); and what no linearisation of the force
captures at an uncertain estimate (the kink noise,
:meth:`.process_noise.ProcessNoise.kink_noise`)."""

import numpy as np
from scipy.special import erfc, ndtr


def expected_positive_part(a):
    """``E max(a - Z, 0) = a Phi(a) + phi(a)``, Z standard normal (shape of ``a``; complex-step
    safe): the mean force of a tension-only string, in units of the jitter's std, whose tension
    margin is ``a`` of them."""
    Phi = 0.5 * erfc(-a / np.sqrt(2.0))
    return a * Phi + np.exp(-0.5 * a * a) / np.sqrt(2.0 * np.pi)


def kink_weight(a):
    """Mean square of ``max(a - Z, 0) - max(a, 0)``, Z standard normal (shape of ``a``).

    The error of a tension-only string's force, in units of the jitter's variance, when its
    rest length jitters by ``Z`` standard deviations and ``a`` is its tension margin in the
    same units: 0 deep slack (``a << 0``), 1/2 at the kink, 1 well taut (the jitter's full
    variance); continuous and increasing.
    """
    a = np.asarray(a, dtype=float)
    Phi = ndtr(a)
    phi = np.exp(-0.5 * a * a) / np.sqrt(2.0 * np.pi)
    slack = (a * a + 1.0) * Phi + a * phi
    taut = Phi - a * phi + a * a * (1.0 - Phi)
    return np.where(a <= 0.0, slack, taut)


def unexplained_variance(a, j=0.0):
    """``Var f - Cov(f, Z)^2`` for ``f = (a + Z + j) 1[a + Z > 0]``, Z standard normal (shape of
    ``a`` and ``j``, ``j >= 0``): with ``b = a + j``,
    ``b^2 Phi (1 - Phi) + 2 b phi (1 - Phi) + Phi - a phi - phi^2 - Phi^2 - 2 j Phi phi - j^2
    phi^2`` at ``a``.

    A tension-only string's force when the filter's tension margin is off the estimate by ``Z``
    standard deviations and ``a`` is the estimated margin in the same units, in units of the
    margin's variance: what no straight line in the margin captures of it (the residual of the
    best one, of slope ``Cov(f, Z) = Phi(a) + j phi(a)``). A string that goes taut while it
    lengthens pulls at once with its damping, ``j`` the jump as a length in the same units
    (``(c/k) d(length)/dt``; 0 for a string shortening, whose force starts from zero). About
    ``0.09 (1 + j^2)`` at the kink, 0 away from it (taut or slack, the force is a line there).
    The filter's own line, of slope 0 or 1, misses at least this much.
    """
    a, j = np.asarray(a, dtype=float), np.asarray(j, dtype=float)
    Phi = ndtr(a)
    phi = np.exp(-0.5 * a * a) / np.sqrt(2.0 * np.pi)
    b = a + j
    return (
        b * b * Phi * (1.0 - Phi)
        + 2.0 * b * phi * (1.0 - Phi)
        + Phi
        - a * phi
        - phi * phi
        - Phi * Phi
        - 2.0 * j * Phi * phi
        - j * j * phi * phi
    )
