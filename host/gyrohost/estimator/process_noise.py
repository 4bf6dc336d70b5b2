"""The process model's discrete noise covariance: white node accelerations, random walks of
the wheel speeds, rest lengths and gyro bias, the servos' goal steps, the board's command
timing while the wheels change speed, and the string kinks (the rest-length jitter through
them, the linearisation's error at them).
A part of :class:`~gyrohost.estimator.process_model.ProcessModel`, which provides ``layout``,
``config``, ``dyn``, ``wheel_acceleration`` and its slope, ``substeps``,
``rest_step_var_m2`` and the ``_noise`` cache.
"""

import numpy as np

from gyrotensegrity.fast_jacobian import outer_rows

from . import complex_step
from .kink import expected_positive_part, kink_weight, unexplained_variance

KINK_REACH = 7.0
"""How many of its standard deviations a string's tension margin may lie from its kink for the
linearisation's noise to count: beyond, no line misses more than round-off (``v(7)`` =
4e-14, :func:`.kink.unexplained_variance`)."""


RK4_JUMP_VARIANCE = 1.0 / 36.0
"""Variance of the error of one RK4 step across a jump in the force at a uniform share ``theta``
of the step, as a share of the step: the stages (weights 1/6, 2/3, 1/6 at 0, 1/2, 1) count the
jump for ``5/6`` of the step before the midpoint, ``1/6`` after, where it acts for ``1 -
theta``; the error ``theta - 1/6`` or ``theta - 5/6`` has mean 0 and mean square 1/36."""


class ProcessNoise:
    """Discrete process noise of :class:`~gyrohost.estimator.process_model.ProcessModel`."""

    def noise(self, dt, F=None, x=None, P=None):
        """Discrete process noise covariance over ``dt`` s, shape (n, n).

        White acceleration noise of density ``accel_psd_m2_s3`` on every reduced coordinate
        (integrated exactly into positions and velocities), random walks of the wheel speeds,
        rest lengths (``rest_psd_m2_s``; and, kept as their spread about the lag whatever the
        steps, :meth:`lag_factor`, the resting servos' ``rest_hold_std_m`` and the servos' last
        goal step's, :meth:`goal_stepped`) and the gyro bias; with the step's Jacobian ``F``
        (n, n), the state ``x`` (n,) it linearises about and its covariance ``P`` (n, n), also
        the strings' kinks (:meth:`kink_noise`): the rest-length jitter of density
        ``rest_jitter_psd_m2_s`` through them, and the error of the linearisation where the
        estimate may lie on the wrong side of one.
        """
        Q = self._white_noise(dt)
        steps = self.rest_step_var_m2.any()
        kinks = F is not None and x is not None and P is not None
        timing = None if x is None else self.wheel_timing_psd(x)
        if not (steps or kinks or timing is not None):
            return Q
        Q = Q.copy()
        if timing is not None:
            w = np.arange(self.layout.omega.start, self.layout.omega.stop)
            Q[w, w] += timing * dt
        if steps:
            r = np.arange(self.layout.rest.start, self.layout.rest.stop)
            hold = self.lag_factor(dt)
            Q[r, r] += self.rest_step_var_m2 * (1.0 - hold * hold)
        if kinks:
            n = self.layout.q_dot.stop
            Q[:n, :n] += self.kink_noise(dt, F, x, P)
        return Q

    def lag_factor(self, dt):
        """The step's factor on a rest length's offset from its command: the filter's
        integrator over ``dt`` s of the lag ``servo_lag_s`` (its RK4 substeps). A walk ``var (1
        - factor^2)`` keeps the spread ``var`` about the lag whatever the steps: the hold's, a
        goal step's."""
        n = self.substeps(dt)
        z = -dt / n / self.config.servo_lag_s
        return (1.0 + z * (1.0 + z / 2.0 * (1.0 + z / 3.0 * (1.0 + z / 4.0)))) ** n

    def wheel_timing_psd(self, x):
        """Walk density (n_w,) rad^2/s^3 of the wheel speeds at the state ``x`` (n,) for the
        uncertain time at which the board acts on its commands, or None (no such key, or the
        wheels not commanded).

        A wheel that follows its setpoint ``omega_dot = (target - omega) / lag`` and acts on it
        ``delta`` late is ``delta omega_dot`` off; a walk of density ``2 (std omega_dot)^2 / lag``
        through the lag spreads it by ``(std omega_dot)^2``, with ``std`` =
        ``wheel_command_time_std_s``.
        """
        std, slope = self.config.wheel_command_time_std_s, self.wheel_acceleration_slope()
        if std == 0.0 or slope == 0.0:  # slope -1 / lag where the wheels follow commands
            return None
        rate = self.wheel_acceleration(x[None, self.layout.omega], None)[0]
        return -2.0 * slope * (std * rate) ** 2

    def kink_noise(self, dt, F, x, P):
        """Node-motion covariance (6 m, 6 m) of the strings' force errors at their kinks.

        String i pulls with ``k max(mu_i, 0)``, ``mu_i = min(stretch, stretch + c/k
        d(length)/dt)`` its tension margin as a length (taut while positive); one that goes
        taut lengthens, and its damper pulls at once: the force jumps by ``k J``, ``J = (c/k)
        d(length)/dt``. Three errors of the prediction's force act along the string as if taut,
        each as a rest-length error ``d`` over the step: ``Q = sum_i var_i G_i G_i^T`` with
        ``G_i`` the step's response to the taut string's ``d acceleration / d rest_i``
        (:meth:`taut_columns`), so a slack string at the linearisation point still gets the
        noise of its re-engaging:

        - the rest-length jitter, white with density ``q`` = ``rest_jitter_psd_m2_s`` (per step
          ``N(0, s^2)``, ``s^2 = q / dt``): the force error ``k (max(mu - d, 0) - max(mu,
          0))`` has mean square ``k^2 s^2 w(mu / s)`` (:func:`kink_weight`: 0 deep slack, 1/2
          at the kink, 1 well taut), less the mean the mean kink carries;
        - the linearisation: the estimate's margin is uncertain, ``mu ~ N(mu_hat, sigma^2)``
          with ``sigma^2 = g P g^T`` (``g = d mu / dx``, :meth:`tension_margins`), and no line
          in ``mu`` follows the force: the best leaves ``k^2 sigma^2 v(mu_hat / sigma, J /
          sigma)`` (:func:`unexplained_variance`: ``0.09 (1 + (J / sigma)^2)`` at the kink, 0
          away from it), which ``F P F^T`` cannot carry; an error of a filter step
          (``process_dt_s``), so that a step split by another sample's time gets
          ``process_dt_s / dt`` of it (``G G^T`` grows with the step's square: the parts would
          sum to less than the whole). The filter's own line (the slope at the estimate)
          misses by more, by ``(H - Phi)^2 sigma^2`` and the mean's offset; that part is left
          out: it grows with ``P`` near a kink, and a filter that has lost the structure (the
          nominal scene on an identification run) then grew ``P`` without bound until its bars
          went singular;
        - the step across a jump: a string slack at the step's start that its rate takes taut
          within the step (``mu <= 0 < mu + d(length)/dt dt``) jumps at a time the RK4 stages
          of its substep place to within ``(J / n)^2`` :data:`RK4_JUMP_VARIANCE` of the step
          (``n`` substeps, :meth:`substeps`).
        """
        L = self.layout
        margin, g = self.tension_margins(x)
        sigma2 = np.einsum("ij,jk,ik->i", g, P[: L.n_dynamic, : L.n_dynamic], g)
        var = np.zeros_like(margin)
        near = (sigma2 > 0.0) & (np.abs(margin) < KINK_REACH * np.sqrt(sigma2))
        share = self.config.process_dt_s / dt  # a split step's parts: the whole step's, summed
        s_dot = self.string_lengths(x)[1]
        jump = np.maximum(self.dyn.c_s / self.dyn.k_s * s_dot, 0.0)
        sigma = np.sqrt(sigma2[near])
        var[near] = (
            share * sigma2[near] * unexplained_variance(margin[near] / sigma, jump[near] / sigma)
        )
        tautening = (margin <= 0.0) & (margin + s_dot * dt > 0.0) & (jump > 0.0)
        var[tautening] += RK4_JUMP_VARIANCE * (jump[tautening] / self.substeps(dt)) ** 2
        q = self.config.rest_jitter_psd_m2_s
        if q > 0.0:
            a = margin / np.sqrt(q / dt)
            w = kink_weight(a)
            if self.config.kink_model == "mean":  # the prediction carries the mean already
                w = w - (expected_positive_part(a) - np.maximum(a, 0.0)) ** 2
            var += (q / dt) * w
        n = L.q_dot.stop
        if not var.any():  # every string a line to round-off: no Jacobian needed
            return np.zeros((n, n))
        G = self.taut_columns(dt, F, x, margin)
        return (G * var) @ G.T

    def tension_margins(self, x):
        """The strings' tension margins ``mu`` (alpha,) m (:meth:`kink_noise`) at ``x`` and
        their gradient ``d mu / dx`` (alpha, n_dynamic), each on the side of its ``min`` that
        holds there, the stretch on a tie: in closed form where the Jacobian is
        (:meth:`string_slopes`), else by the complex step."""
        L = self.layout
        if self.jac is None:
            X = complex_step.perturbed(x[: L.n_dynamic], self.columns)
            stretch, damped = self.margins(X)
            pick = damped.real < stretch.real
            return complex_step.split(np.where(pick, damped, stretch))
        q, q_dot = x[L.q].reshape(3, L.m), x[L.q_dot].reshape(3, L.m)
        s, s_dot, u, d_S, d_S_dot = self.string_slopes(q, q_dot)
        damping = self.dyn.c_s / self.dyn.k_s * s_dot
        damped = damping < 0.0
        g = np.zeros((L.n_strings, L.n_dynamic))
        g[:, L.q] = outer_rows(np.where(damped, d_S, u), self.jac.Es)
        g[:, L.q_dot] = outer_rows(np.where(damped, d_S_dot, 0.0), self.jac.Es)
        g[:, L.rest] = -np.eye(L.n_strings)
        return s - x[L.rest] + np.where(damped, damping, 0.0), g

    def string_slopes(self, q, q_dot):
        """The strings' lengths ``s`` (alpha,) m, rates ``s_dot`` (alpha,) m/s and directions
        ``u`` (3, alpha), and the gradients (3, alpha) of their damped stretch ``s + (c/k)
        s_dot`` with respect to each string's vector ``S`` and its rate: ``u + (c/k) (S_dot -
        s_dot u) / s`` and ``(c/k) u``; at one real state ``q``, ``q_dot`` (3, m), through the
        closed-form Jacobian's member maps."""
        dyn = self.dyn
        S = (q @ self.jac.EE_T + dyn.off)[:, dyn.beta :]
        S_dot = q_dot @ self.jac.EE_T[:, dyn.beta :]
        s = np.sqrt((S * S).sum(axis=0))
        u = S / s
        s_dot = (u * S_dot).sum(axis=0)
        ratio = dyn.c_s / dyn.k_s
        return s, s_dot, u, u + ratio * (S_dot - s_dot * u) / s, ratio * u

    def margins(self, X):
        """Stretch (K, alpha) and damped stretch ``stretch + c/k d(length)/dt`` (K, alpha), m,
        of a batch of states ``X`` (K, n_dynamic), real or complex."""
        s, s_dot = self.string_lengths(X)
        stretch = s - X[:, self.layout.rest]
        return stretch, stretch + self.dyn.c_s / self.dyn.k_s * s_dot

    def taut_columns(self, dt, F, x, margin):
        """Response of the node motion over a step to every rest length, each string as if taut
        (``margin``: the strings' tension margins ``mu`` (alpha,) m at ``x``,
        :meth:`tension_margins`).

        Returns
        -------
        G : ndarray, shape (6 m, alpha)
            ``dt/2 (b_i + F b_i)`` (trapezoid rule for the integral of the step's transition
            over the step), ``b_i`` = (0, d eta2_ddot / d rest_i) of string i held taut, m/m
            and (m/s)/m.
        """
        L = self.layout
        a = self.taut_rest_columns(x, margin)
        n = L.q_dot.stop
        G = F[:n, L.q_dot] @ a
        G[L.q_dot] += a
        return 0.5 * dt * G

    def taut_rest_columns(self, x, margin):
        """``d eta2_ddot / d rest`` (3 m, alpha) at ``x``, each string held taut (``margin``
        as :meth:`taut_columns`)."""
        # the string force is affine in its rest length while taut (slope -k along the string)
        # and the accelerations are affine in the string forces: any taut point gives the
        # column; 1 mm of margin keeps every string taut whatever its state
        return self._rest_columns(x, x[self.layout.rest] - np.maximum(-margin, 0.0) - 1e-3)

    def _rest_columns(self, x, rest):
        """``d eta2_ddot / d rest`` (3 m, alpha) at the state ``x`` with rest lengths ``rest``:
        in closed form (one evaluation: a column depends on its own string only) or by the
        complex step."""
        L, m, alpha = self.layout, self.layout.m, self.layout.n_strings
        if self.jac is not None:
            q, q_dot = x[L.q].reshape(3, m), x[L.q_dot].reshape(3, m)
            return self.jac(q, q_dot, x[L.omega], rest)[1][:, L.rest]
        X = np.tile(x[: L.n_dynamic].astype(complex), (alpha, 1))
        X[:, L.rest] = rest
        X[np.arange(alpha), L.rest.start + np.arange(alpha)] += 1j * complex_step.STEP
        a, _ = self.dyn.accelerations(
            X[:, L.q].reshape(alpha, 3, m),
            X[:, L.q_dot].reshape(alpha, 3, m),
            X[:, L.omega],
            X[:, L.rest],
        )
        return a.reshape(alpha, 3 * m).imag.T / complex_step.STEP

    def string_lengths(self, x):
        """Lengths (..., alpha) m and their rates (..., alpha) m/s of the strings at the state
        ``x`` (..., n) (real or complex)."""
        L, dyn = self.layout, self.dyn
        shape = x.shape[:-1] + (3, L.m)
        # bar and string vectors are EE_T(q) + off (bars first); keep the strings
        Y = (dyn.EE_T(x[..., L.q].reshape(shape)) + dyn.off)[..., dyn.beta :]
        Y_dot = dyn.EE_T(x[..., L.q_dot].reshape(shape))[..., dyn.beta :]
        s = np.sqrt((Y * Y).sum(axis=-2))
        return s, (Y * Y_dot).sum(axis=-2) / s

    def _white_noise(self, dt):
        if dt in self._noise:
            return self._noise[dt]
        L, c = self.layout, self.config
        # built from slices: a step split by wheel and servo samples has a length of its own
        diagonal = np.zeros(L.size)
        qa = c.accel_psd_m2_s3
        diagonal[L.q] = qa * dt**3 / 3.0
        diagonal[L.q_dot] = qa * dt
        diagonal[L.omega] = c.wheel_accel_psd_rad2_s3 * dt
        hold = self.lag_factor(dt)
        diagonal[L.rest] = c.rest_psd_m2_s * dt + c.rest_hold_std_m**2 * (1.0 - hold * hold)
        diagonal[L.bias] = c.gyro_bias_psd_rad2_s3 * dt
        diagonal[L.accel_bias] = c.accel_bias_psd_m2_s5 * dt
        Q = np.diag(diagonal)
        np.fill_diagonal(Q[L.q, L.q_dot], qa * dt**2 / 2.0)  # position with velocity
        np.fill_diagonal(Q[L.q_dot, L.q], qa * dt**2 / 2.0)
        if len(self._noise) < 8:  # the steps repeat (10 ms); keep a few
            self._noise[dt] = Q
        return Q
