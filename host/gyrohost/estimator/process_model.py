"""Discrete process model of the filter: the tensegrity dynamics, stepped, with its Jacobian.

Two variants (``process_method``):

``lean`` (default)
    Classic RK4 in as few equal substeps of the filter step (10 ms) as keep its error on the
    model's fastest oscillation within :data:`RK4_STEP_ERROR` (two on the simulated D-bar, one
    on the prism), and ``F`` its Jacobian by the chain rule through the stages' ``A = df/dx``
    (below), the first one the accelerometer fusion's where it has just made one at the prior
    (the posterior differs from it by the update only). Both matter: with one step, or with
    ``F`` from the start's ``A`` alone (``I + A dt + ... + (A dt)^4/24``), the mean and the
    covariance stray from a structure that turns while a string holds it, and the NEES grows
    without bound (docs/estimator-noise.md, "Node accelerations"). Where a string turns taut
    or slack within a substep the true Jacobian jumps and this F is only an average.
``rk4``
    RK4 with substeps of at most ``rk4_substep_s``, differentiated exactly through every stage
    (the complex-step batch pushed through, or the stages' closed-form Jacobians chained).

``A = df/dx`` comes in closed form (``jacobian = "analytic"``, the default:
:class:`gyrotensegrity.fast_jacobian.FastJacobian`; both variants then chain the stages'
Jacobians) or from one batched complex-step evaluation through
:class:`gyrotensegrity.fast.FastDynamics` (``"complex-step"``); the two agree to round-off
(tests/estimator/test_jacobians.py).

The lean model steps with RK4, not exponential Euler (``x + dt phi1(A dt) f``): at 10 ms the
latter's velocity error per step is twenty times RK4's (docs/estimator.md).

The wheel speeds follow the model (torque wheels: ``torque / J_3``; speed wheels: held), or,
given the wheel board's commands (:attr:`ProcessModel.wheel_command_rad_s`) and
``wheel_lag_s > 0``, those commands as the board does: its setpoint ramps to the command at
``wheel_accel_rad_s2`` (deterministic, kept here outside the filter state, a known function of
time in each Runge-Kutta stage) and the wheel follows the setpoint with the lag
``wheel_lag_s``; the rest
lengths follow the commanded ones through a first-order lag ``servo_lag_s`` (the servos'
response; at most at their speed limit, through the input :mod:`.servo_motion` gives each
step); the gyro bias is constant. Process noise is white: node accelerations
(``accel_psd_m2_s3``), random walks of wheel speeds, rest lengths and bias;
:meth:`ProcessModel.noise` gives its discrete covariance.
"""

import numpy as np
from scipy.special import ndtr

from gyrotensegrity.diagnostics import highest_frequency
from gyrotensegrity.fast import FastDynamics
from gyrotensegrity.fast_jacobian import FastJacobian, JacobianUnsupported, outer_rows

from . import complex_step
from .errors import EstimatorConfigError
from .kink import expected_positive_part
from .layout import layout_of
from .motor_reaction import MotorReaction
from .process_noise import ProcessNoise

RK4_STEP_ERROR = 1e-3
"""RK4's largest error per substep on the model's fastest oscillation, as a share of its
amplitude: ``(omega h)^5 / 120`` (the leading term of ``exp(i omega h)`` less RK4's
polynomial), so substeps of ``omega h <= (120 RK4_STEP_ERROR)^(1/5)`` = 0.65. One 10 ms step
of the D-bar's strings (120 rad/s) errs by 2 % per step: the mean strays from a structure that
drifts while a slack string leaves it a mechanism, the filter's noise says nothing of it, and
its NEES grows without bound; at this share it stays at its dof with no node noise, and halving
the substep changes no figure (docs/estimator-noise.md, "Node accelerations")."""

RK4_ACCURATE = (120.0 * RK4_STEP_ERROR) ** 0.2
"""``omega h`` of a substep whose error is :data:`RK4_STEP_ERROR`."""


def accurate_substep(model) -> float:
    """The longest RK4 substep, s, that keeps the error on ``model``'s fastest oscillation
    (:func:`gyrotensegrity.diagnostics.highest_frequency`) within :data:`RK4_STEP_ERROR`; inf
    for a model with no oscillation."""
    omega, _ = highest_frequency(model)
    return RK4_ACCURATE / omega if omega > 0.0 else np.inf


def on_wire(omega_rad_s, config):
    """Wheel speeds (n_w,) rad/s rounded to the board's wire step ``wheel_resolution_rad_s``
    (unchanged where it is 0), as the driver sends them."""
    step = config.wheel_resolution_rad_s
    return np.round(omega_rad_s / step) * step if step > 0.0 else omega_rad_s


def check_model(model) -> None:
    """Raise :class:`EstimatorConfigError` for models the estimator does not support."""
    if model.beta == 0:
        raise EstimatorConfigError(f"scene {model.scene.name!r}: the estimator needs bars")


class ProcessModel(ProcessNoise):
    """The filter's discrete process model (its noise: :class:`ProcessNoise`).

    Parameters
    ----------
    model : gyrotensegrity.Model
    config : EstimatorConfig
    """

    def __init__(self, model, config):
        self.model = model
        self.config = config
        # the model's fast path: batched and complex-step safe, the compiled kernel for real
        # single states; tests/model/test_fast.py compares it with the reference rhs
        self.dyn = FastDynamics(model)
        self.layout = layout_of(model)
        self.columns = np.arange(self.layout.n_dynamic)
        self.lean_substep_s = accurate_substep(model)
        """The lean model's longest RK4 substep, s (:func:`accurate_substep`)."""
        self._noise: dict[float, np.ndarray] = {}
        self.wheel_command_rad_s: np.ndarray | None = None
        """Commanded spins (n_w,) rad/s the wheels follow (``wheel_lag_s`` > 0); None: the
        model's wheel input."""
        self.wheel_setpoint_rad_s: np.ndarray | None = None
        """The board's ramped setpoints (n_w,) rad/s at the filter's time."""
        self.wheel_target_rad_s: np.ndarray | None = None
        """The setpoints the wheels are pulled towards in this derivative evaluation, rad/s."""
        self.jac = self._closed_form() if config.jacobian == "analytic" else None
        self.reaction = MotorReaction(self.dyn) if config.wheel_reaction == "body" else None
        """The wheels' reaction on the whole structure (hinged rig), or None (the paper's)."""
        self.rest_step_var_m2 = np.zeros(self.layout.n_strings)
        """Spread (alpha,) m^2 the rest lengths keep about their lag from the last goal step."""
        self._commanded = False  # the first goals set the lag's target, they are no step

    def _closed_form(self):
        try:
            return FastJacobian(self.dyn)
        except JacobianUnsupported as exc:
            raise EstimatorConfigError(f"estimator key 'jacobian' is 'analytic': {exc}") from None

    def derivative(self, X, u, with_node_accelerations=False):
        """dx/dt of the dynamic part of a batch of filter states (and N_ddot (K, 3, n) if asked).

        Parameters
        ----------
        X : ndarray, shape (K, n_dynamic), real or complex
        u : ndarray, shape (alpha + n_w,)
            Commanded rest lengths (m), then wheel inputs; the rest-length states follow the
            command with the servo lag ``servo_lag_s``.

        Returns
        -------
        ndarray, shape (K, n_dynamic)
        """
        L, m, K = self.layout, self.layout.m, X.shape[0]
        q = X[:, L.q].reshape(K, 3, m)
        q_dot = X[:, L.q_dot].reshape(K, 3, m)
        rest = X[:, L.rest]
        pulling = rest  # the rest lengths the string forces see
        if self.config.kink_model == "mean":
            pulling = self.mean_force_rest(q, q_dot, rest)
        omega = X[:, L.omega]
        if with_node_accelerations:
            eta2_ddot, N_ddot = self.dyn.accelerations(q, q_dot, omega, pulling)
        else:
            eta2_ddot = self.dyn.reduced_accelerations(q, q_dot, omega, pulling)
        dx = np.empty_like(X)
        dx[:, L.omega] = self.wheel_acceleration(omega, u)
        if self.reaction is not None:
            turn = self.reaction.accelerations(q, dx[:, L.omega])
            eta2_ddot = eta2_ddot + turn
            if with_node_accelerations:
                N_ddot = N_ddot + self.dyn.node_values(turn)
        dx[:, L.q] = X[:, L.q_dot]
        dx[:, L.q_dot] = eta2_ddot.reshape(K, 3 * m)
        dx[:, L.rest] = self.rest_rate(rest, u)
        return (dx, N_ddot) if with_node_accelerations else dx

    def command_wheels(self, omega_rad_s) -> None:
        """The wheel board's commanded spins (n_w,) rad/s from now on; the first command is
        taken as the setpoint reached (the run starts the filter with the wheels steady). The
        board spins to them rounded to its wire's step (``wheel_resolution_rad_s``)."""
        self.wheel_command_rad_s = on_wire(np.array(omega_rad_s, float), self.config)
        if self.wheel_setpoint_rad_s is None:
            self.wheel_setpoint_rad_s = self.wheel_command_rad_s.copy()
            self.wheel_target_rad_s = self.wheel_command_rad_s.copy()

    def goal_stepped(self, step_m) -> None:
        """The servos' goals moved by ``step_m`` (alpha,) m.

        A goal reaches the servo at a time known only to ``servo_time_std_s``: through the lag
        its position strays by ``|step| time std / lag`` (``servo_step_std_ratio |step|``; for
        a servo that covers its goal step at its moving speed and holds, ``1/sqrt(12)``, a
        position uniform over the step). That spread the rest lengths keep about their lag
        until the next goal (:meth:`lag_factor`, as the hold).
        """
        step = np.asarray(step_m, float) if self._commanded else np.zeros(len(step_m))
        self.rest_step_var_m2 = (self.config.servo_step_std_ratio * step) ** 2
        self._commanded = True

    def _aim(self, sp0, tau_s: float) -> None:
        """Point the wheels at the setpoints ``tau_s`` s after they were ``sp0`` (the stage's
        time within the step)."""
        if sp0 is not None:
            a = self.config.wheel_accel_rad_s2 * tau_s
            self.wheel_target_rad_s = sp0 + np.clip(self.wheel_command_rad_s - sp0, -a, a)

    def rest_rate(self, rest, u):
        """Rates (..., alpha) m/s of the rest lengths ``rest`` (..., alpha) m, real or complex:
        their first-order lag ``servo_lag_s`` behind the commanded ones in the input ``u``."""
        return (u[: self.layout.n_strings] - rest) / self.config.servo_lag_s

    def servo_speed(self, rest, u):
        """The servos' string speeds (alpha,) m/s at rest lengths ``rest`` (alpha,) under ``u``:
        the lag's rate (:meth:`rest_rate`), at most their speed limit ``servo_speed_m_s``."""
        limit = self.config.servo_speed_m_s
        return np.clip(self.rest_rate(rest, u), -limit, limit)

    def wheel_acceleration(self, omega, u):
        """Spin accelerations (K, n_w) rad/s^2 of the wheel states ``omega`` (K, n_w), real or
        complex: the lag behind the board's setpoints when commanded, else the model's."""
        target, lag = self.wheel_target_rad_s, self.config.wheel_lag_s
        if target is None or lag == 0.0:
            return np.broadcast_to(self.dyn.wheel_acceleration(u), omega.shape)
        return (target - omega) / lag

    def wheel_jerk(self, omega_dot):
        """Rate of the spin accelerations (n_w,) rad/s^3 where they are ``omega_dot`` (n_w,)
        rad/s^2 (:meth:`wheel_acceleration`): ``(d setpoint/dt - d omega/dt) / lag``, the
        setpoint ramping at ``wheel_accel_rad_s2`` towards the command while short of it;
        zeros where the wheels are not commanded."""
        lag = self.config.wheel_lag_s
        if self.wheel_command_rad_s is None or lag == 0.0:
            return np.zeros_like(omega_dot)
        ramp = self.config.wheel_accel_rad_s2 * np.sign(
            self.wheel_command_rad_s - self.wheel_setpoint_rad_s
        )
        return (ramp - omega_dot) / lag

    def wheel_acceleration_slope(self) -> float:
        """d(wheel acceleration)/d omega of each wheel, 1/s: ``-1 / wheel_lag_s`` where the wheels
        follow commands, else 0 (the model's spin accelerations do not depend on the spins)."""
        if self.wheel_target_rad_s is None or self.config.wheel_lag_s == 0.0:
            return 0.0
        return -1.0 / self.config.wheel_lag_s

    def mean_force_rest(self, q, q_dot, rest):
        """Rest lengths (K, alpha) m at which every string pulls with its expected force under
        the rest-length jitter (per step ``N(0, s^2)``, ``s^2 = rest_jitter_psd_m2_s /
        process_dt_s``): ``k s g(mu / s)``, ``g(a) = E max(a - Z, 0) = a Phi(a) + phi(a)``, with
        ``mu = stretch + (c/k) d(length)/dt`` the tension margin as a length; a smooth kink (a
        softplus of width ``s``) that equals the sharp one a few ``s`` away from it.

        Parameters
        ----------
        q, q_dot : ndarray, shape (K, 3, m), m and m/s (real or complex: complex-step safe)
        rest : ndarray, shape (K, alpha), m
        """
        dyn = self.dyn
        s_j = np.sqrt(self.config.rest_jitter_psd_m2_s / self.config.process_dt_s)
        if s_j == 0.0:
            return rest
        Y = (dyn.EE_T(q) + dyn.off)[..., dyn.beta :]
        Y_dot = dyn.EE_T(q_dot)[..., dyn.beta :]
        length = np.sqrt((Y * Y).sum(axis=-2))
        margin = length - rest + dyn.c_s / dyn.k_s * (Y * Y_dot).sum(axis=-2) / length
        return rest + margin - s_j * expected_positive_part(margin / s_j)

    def mean_force_rest_jacobian(self, q, q_dot, rest):
        """:meth:`mean_force_rest` of one real state (alpha,) m and its Jacobian (alpha,
        n_dynamic) with respect to the filter's dynamic state.

        With ``margin = t / k`` (the tension at ``rest`` as a length) and ``g' = Phi``:
        ``d pulling = Phi(a) d rest + (1 - Phi(a)) (d margin + d rest)``, ``d margin + d rest =
        u . dS + (c/k) ((S_dot - s_dot u) . dS / s + u . dS_dot)`` (string vector ``S``, length
        ``s``, direction ``u``).
        """
        L, dyn = self.layout, self.dyn
        D = np.zeros((L.n_strings, L.n_dynamic))
        s_j = np.sqrt(self.config.rest_jitter_psd_m2_s / self.config.process_dt_s)
        D[:, L.rest] = np.eye(L.n_strings)
        if s_j == 0.0:
            return rest, D
        s, s_dot, _, d_S, d_S_dot = self.string_slopes(q, q_dot)
        margin = s - rest + dyn.c_s / dyn.k_s * s_dot
        a = margin / s_j
        open_ = 1.0 - ndtr(a)  # d pulling / d margin
        Es = self.jac.Es
        D[:, L.q] = outer_rows(open_ * d_S, Es)
        D[:, L.q_dot] = outer_rows(open_ * d_S_dot, Es)
        D[:, L.rest] = np.diag(1.0 - open_)
        return rest + margin - s_j * expected_positive_part(a), D

    def closed_form(self, x, u):
        """The dynamics and their Jacobian in closed form (``jacobian = "analytic"``).

        Parameters
        ----------
        x : ndarray, shape (n_dynamic,) or longer (the bias is ignored)
        u : ndarray, shape (alpha + n_w,)

        Returns
        -------
        f : ndarray, shape (n_dynamic,)
        A : ndarray, shape (n_dynamic, n_dynamic)
        z_ddot : ndarray, shape (3, m), m/s^2: the reduced accelerations
        J : ndarray, shape (3 m, n_dynamic): their Jacobian (the rows of ``A`` for ``q_dot``)
        """
        L, m = self.layout, self.layout.m
        q, q_dot, rest = x[L.q].reshape(3, m), x[L.q_dot].reshape(3, m), x[L.rest]
        if self.config.kink_model == "mean":
            pulling, d_pulling = self.mean_force_rest_jacobian(q, q_dot, rest)
            z_ddot, J = self.jac(q, q_dot, x[L.omega], pulling)
            through_pulling = J[:, L.rest] @ d_pulling  # the forces see the pulling lengths
            J[:, L.rest] = 0.0
            J += through_pulling
        else:
            z_ddot, J = self.jac(q, q_dot, x[L.omega], rest)
        if self.reaction is not None:
            turn, d_turn = self.reaction.jacobian(x, L, lambda w: self.wheel_acceleration(w, u))
            z_ddot, J = z_ddot + turn.reshape(3, m), J + d_turn
        nd = L.n_dynamic
        A = np.zeros((nd, nd))
        A[L.q, L.q_dot] = np.eye(3 * m)
        A[L.q_dot] = J
        A[L.rest, L.rest] = -np.eye(L.n_strings) / self.config.servo_lag_s
        A[L.omega, L.omega] = self.wheel_acceleration_slope() * np.eye(L.n_wheels)
        f = np.empty(nd)
        f[L.q] = x[L.q_dot]
        f[L.q_dot] = z_ddot.ravel()
        f[L.omega] = self.wheel_acceleration(x[None, L.omega], u)[0]
        f[L.rest] = self.rest_rate(rest, u)
        return f, A, z_ddot, J

    def linearise(self, x, u):
        """``f(x)`` (n_dynamic,) and ``A = df/dx`` (n_dynamic, n_dynamic): by the complex step
        or in closed form (``jacobian``)."""
        if self.jac is not None:
            return self.closed_form(x, u)[:2]
        X = complex_step.perturbed(x[: self.layout.n_dynamic], self.columns)
        return complex_step.split(self.derivative(X, u))

    def step(self, x, u, dt, A=None):
        """Advance the filter state by ``dt`` seconds under input ``u``.

        Parameters
        ----------
        x : ndarray, shape (n,)
        u : ndarray, shape (alpha + n_w,)
        dt : float, s
        A : ndarray, shape (n_dynamic, n_dynamic), optional
            A linearisation to use for ``F`` (lean model); default: made at ``x``.

        Returns
        -------
        x_next : ndarray, shape (n,)
        F : ndarray, shape (n, n)
            Jacobian of ``x_next`` with respect to ``x``.
        """
        nd = self.layout.n_dynamic
        sp0 = self.wheel_setpoint_rad_s
        if self.config.process_method == "rk4":
            xd, Fd = self._rk4(x[:nd], u, dt, sp0)
        else:
            xd, Fd = self._lean(x[:nd], u, dt, A, sp0)
        self.setpoints_moved(sp0, dt)
        F = np.eye(x.size)
        F[:nd, :nd] = Fd
        return np.concatenate([xd, x[nd:]]), F

    def setpoints_moved(self, sp0, dt) -> None:
        """The board's setpoints ``dt`` s after they were ``sp0`` (a step's end)."""
        self._aim(sp0, dt)
        self.wheel_setpoint_rad_s = self.wheel_target_rad_s

    def _lean(self, xd, u, dt, A, sp0):
        return self._rk4_closed_form(xd, u, dt, sp0, A, carry=True)

    def substeps(self, dt) -> int:
        """RK4 substeps the process model takes over ``dt`` s, each at most
        ``lean_substep_s`` (lean) or ``rk4_substep_s`` (rk4) long."""
        c = self.config
        longest = self.lean_substep_s if c.process_method == "lean" else c.rk4_substep_s
        return max(1, int(np.ceil(dt / longest - 1e-9)))

    def _rk4(self, xd, u, dt, sp0):
        if self.jac is not None:
            return self._rk4_closed_form(xd, u, dt, sp0)
        X = self._rk4_substeps(complex_step.perturbed(xd, self.columns), u, dt, sp0)
        return complex_step.split(X)

    def _rk4_substeps(self, X, u, dt, sp0):
        """The batch of states ``X`` (K, n_dynamic) after :meth:`substeps` RK4 substeps over
        ``dt`` s."""
        n = self.substeps(dt)
        h = dt / n
        for j in range(n):
            k1, k2, k3, k4 = self._rk4_stages(X, u, h, sp0, j * h)
            X = X + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return X

    def _rk4_closed_form(self, x, u, dt, sp0, A_first=None, carry=False):
        """:meth:`substeps` RK4 substeps of ``h`` over ``dt`` s with the step's Jacobian by the
        chain rule through the stages (``d k_i = A(x_i) d x_i``; the wheels' setpoints at each
        stage's time), the first stage's ``A`` given in ``A_first`` where a caller made it at
        ``x``; with ``carry`` every later substep's first ``A`` is the one before's last (made
        at ``x + h k3``, within ``h^2`` of the substep's start: one Jacobian fewer per substep,
        the lean model's NEES unchanged)."""
        n = self.substeps(dt)
        h = dt / n
        eye = np.eye(len(x))
        F, A_next = eye, A_first
        for j in range(n):
            self._aim(sp0, j * h)
            if A_next is not None:
                k1, A1 = self.derivative(x[None, :], u)[0], A_next
            else:
                k1, A1 = self.linearise(x, u)
            self._aim(sp0, (j + 0.5) * h)
            k2, A2 = self.linearise(x + 0.5 * h * k1, u)
            D2 = A2 @ (eye + 0.5 * h * A1)
            k3, A3 = self.linearise(x + 0.5 * h * k2, u)
            D3 = A3 @ (eye + 0.5 * h * D2)
            self._aim(sp0, (j + 1) * h)
            k4, A4 = self.linearise(x + h * k3, u)
            D4 = A4 @ (eye + h * D3)
            x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            F = (eye + (h / 6.0) * (A1 + 2.0 * D2 + 2.0 * D3 + D4)) @ F
            A_next = A4 if carry else None
        return x, F

    def _rk4_stages(self, X, u, h, sp0, t_s):
        """The four RK4 slopes over ``h`` from ``X``, ``t_s`` s into the step (the wheels'
        setpoints at each stage's time)."""
        self._aim(sp0, t_s)
        k1 = self.derivative(X, u)
        self._aim(sp0, t_s + 0.5 * h)
        k2 = self.derivative(X + 0.5 * h * k1, u)
        k3 = self.derivative(X + 0.5 * h * k2, u)
        self._aim(sp0, t_s + h)
        k4 = self.derivative(X + h * k3, u)
        return k1, k2, k3, k4
