"""Online fit of the wheel-momentum gain: what corrects a wrong wheel inertia in the plan.

Model (:mod:`.reduced`, with the wheel momentum scaled by an unknown gain ``kappa``)::

    I_a(d) w = H - kappa h_w(d) . omega_w

is linear in the unknowns ``(H, kappa)``: every estimate of the shape ``d`` (n1-n3 distance,
m) and the tilt rate ``w`` (rad/s) is one linear observation. The fit is Bayesian least
squares in information form: a prior (``kappa`` = 1, ``H`` = the wheel momentum at the start)
plus one row per sample, weighted by an assumed tilt-rate noise. ``kappa`` becomes observable
once the shape has moved (``h_w(d)`` changes); before that the prior holds it at 1.
"""

import numpy as np


class WheelGainFit:
    """Estimate ``(H, kappa)`` from shape and tilt-rate samples.

    Parameters
    ----------
    dbar : DBarReduced
    momentum0 : float, kg m^2/s
        Prior mean of ``H`` (the momentum about the tilt axis at the start).
    omega_w : ndarray, shape (n_w,), rad/s
        Wheel spins.
    kappa_std : float
        Prior standard deviation of ``kappa`` (relative).
    momentum_std : float
        Prior standard deviation of ``H`` relative to ``|momentum0|``.
    rate_std_rad_s : float, rad/s
        Noise of one tilt-rate sample.
    """

    def __init__(
        self, dbar, momentum0, omega_w, kappa_std=0.5, momentum_std=0.5, rate_std_rad_s=0.02
    ):
        self.dbar, self.omega_w, self.rate_std = dbar, np.asarray(omega_w, float), rate_std_rad_s
        s_H = momentum_std * max(abs(momentum0), 1e-12)
        self.info = np.diag([1.0 / s_H**2, 1.0 / kappa_std**2])
        self.vec = self.info @ np.array([momentum0, 1.0])
        self.samples = 0

    def add(self, d_m, rate_rad_s):
        """One sample: n1-n3 distance ``d_m`` (m) and tilt rate ``rate_rad_s`` (rad/s)."""
        inertia = float(self.dbar.inertia(d_m))
        phi = np.array([1.0, -float(self.dbar.wheel_momentum(d_m, self.omega_w))])
        weight = 1.0 / (inertia * self.rate_std) ** 2
        self.info += weight * np.outer(phi, phi)
        self.vec += weight * phi * inertia * rate_rad_s
        self.samples += 1

    def estimate(self):
        """``(H, kappa, kappa_std)``: momentum (kg m^2/s), gain and its standard deviation."""
        mean = np.linalg.solve(self.info, self.vec)
        cov = np.linalg.inv(self.info)
        return float(mean[0]), float(mean[1]), float(np.sqrt(cov[1, 1]))
