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

from gyrotensegrity.diagnostics import angular_momentum

from .attitude_model import centre_of_mass, params_at


class _LinearFit:
    """Bayesian least squares in information form: a Gaussian prior on the unknowns (``mean``,
    ``std``, independent) plus weighted linear observations ``rows @ theta = y``."""

    def __init__(self, mean, std):
        self.info = np.diag(1.0 / np.asarray(std, float) ** 2)
        self.vec = self.info @ np.asarray(mean, float)
        self.samples = 0

    def _observe(self, rows, y, weight) -> None:
        rows = np.atleast_2d(rows)
        self.info += weight * rows.T @ rows
        self.vec += weight * rows.T @ np.atleast_1d(y)
        self.samples += 1

    def _posterior(self):
        """Mean and covariance of the unknowns."""
        return np.linalg.solve(self.info, self.vec), np.linalg.inv(self.info)


class WheelGainFit(_LinearFit):
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
        super().__init__([momentum0, 1.0], [s_H, kappa_std])

    def add(self, d_m, rate_rad_s):
        """One sample: n1-n3 distance ``d_m`` (m) and tilt rate ``rate_rad_s`` (rad/s)."""
        inertia = float(self.dbar.inertia(d_m))
        phi = np.array([1.0, -float(self.dbar.wheel_momentum(d_m, self.omega_w))])
        self._observe(phi, inertia * rate_rad_s, 1.0 / (inertia * self.rate_std) ** 2)

    def estimate(self):
        """``(H, kappa, kappa_std)``: momentum (kg m^2/s), gain and its standard deviation."""
        mean, cov = self._posterior()
        return float(mean[0]), float(mean[1]), float(np.sqrt(cov[1, 1]))


class MomentumGainFit(_LinearFit):
    """The three-axis form of :class:`WheelGainFit`: estimate the total momentum ``H0`` (3,
    kg m^2/s, start-frame axes) and the wheel-momentum gain ``kappa`` of any free scene from
    full-state estimates. Each is one linear observation (three rows)::

        L_i = H0 - kappa W_i

    with ``W_i`` the wheels' spin momentum the model gives at the estimate and ``L_i`` the rest
    of its momentum (the structure's). Priors as :class:`WheelGainFit`'s; the rows weighted by
    a body-rate noise ``rate_std_rad_s`` times the locked inertia's largest principal value at
    the start.

    Parameters
    ----------
    reduced : AttitudeModel
    x0 : ndarray
        A full state of ``reduced.model`` (the start): the prior mean of ``H0``.
    kappa_std, momentum_std, rate_std_rad_s : float
        As :class:`WheelGainFit`'s.
    """

    def __init__(self, reduced, x0, kappa_std=0.5, momentum_std=0.5, rate_std_rad_s=0.02):
        self.reduced, self.u = reduced, reduced.model.input_at(0.0)
        inertia = float(np.linalg.eigvalsh(params_at(reduced.model, x0, self.u).I_b)[-1])
        self.weight = 1.0 / (inertia * rate_std_rad_s) ** 2
        H0 = np.sum(self.split(x0), axis=0)
        s_H = momentum_std * max(float(np.linalg.norm(H0)), 1e-12)
        super().__init__(np.append(H0, 1.0), [s_H] * 3 + [kappa_std])

    def split(self, x):
        """``(L, W)``: the structure's and the wheels' spin momentum (3,) kg m^2/s, start-frame
        axes, about the centre of mass, of the full state ``x``."""
        model = self.reduced.model
        N, N_dot = model.nodes(x)
        omega_w = model.wheel_speeds(x, self.u)
        centre, velocity = centre_of_mass(model, N), centre_of_mass(model, N_dot)
        total = angular_momentum(model, N - centre[:, None], N_dot - velocity[:, None], omega_w)
        wheels = angular_momentum(model, N, np.zeros_like(N), omega_w)  # spin alone
        F0 = self.reduced.frame.F0
        return F0.T @ (total - wheels), F0.T @ wheels

    def add_state(self, x):
        """One estimate (a full state of the model)."""
        locked, wheels = self.split(x)
        self._observe(np.hstack([np.eye(3), -wheels[:, None]]), locked, self.weight)

    def estimate(self):
        """``(H0, kappa, kappa_std)``: momentum (3,) kg m^2/s, gain and its standard
        deviation."""
        mean, cov = self._posterior()
        return mean[:3], float(mean[3]), float(np.sqrt(cov[3, 3]))
