"""A tension-only string under a rest-length jitter: the mean of its rectified force and the
mean square of its error, in units of the jitter's std (the process model's ``kink_model =
"mean"`` and its jitter noise, docs/estimator.md); and the error of the force's linearisation
at an uncertain estimate (the kink noise, :meth:`.process_noise.ProcessNoise.kink_noise`)."""

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


def linearisation_residual(a):
    """Mean square of ``max(a + Z, 0) - max(a, 0) - H(a) Z``, Z standard normal, ``H`` the step
    function (shape of ``a``).

    The error of a tension-only string's force beyond the filter's linearisation at its estimate,
    in units of the estimate's variance of the tension margin, when the margin is off the
    estimate by ``Z`` standard deviations and ``a`` is the estimated margin in the same units:
    the part of the rectifier the line through the estimate misses, ``E((Z - |a|)+)^2 =
    (a^2 + 1) Phi(-|a|) - |a| phi(a)``; 1/2 at the kink, falling to 0 on both sides (taut or
    slack, the line is exact there).
    """
    b = np.abs(np.asarray(a, dtype=float))
    return (b * b + 1.0) * ndtr(-b) - b * np.exp(-0.5 * b * b) / np.sqrt(2.0 * np.pi)
