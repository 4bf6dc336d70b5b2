"""The extended Kalman filter of a gyroscopic tensegrity structure (filterpy underneath).

State: see :mod:`.layout`; process model: :mod:`.process_model`; measurements: one
``fuse_*`` module per source; manifold: :mod:`.manifold`; status word: :class:`Status`.

Typical use (the run loop and ``gyrotens replay``)::

    ekf = TensegrityEKF(model, config, log=writer)
    ekf.set_input(rest_lengths, t)        # commanded rest lengths from t on, held
    ekf.fuse_imu(t, omega, accel, euler)  # predicts to t, then fuses rate, accel, angle
    ekf.fuse_wheels(t, omega_w)
    ekf.fuse_servos(t, lengths, strings)
    ekf.advance(t)                        # prediction only (between samples, during outages)
"""

import bisect
from collections import deque
from enum import IntFlag

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from gyrotensegrity import SimulationError

from . import fuse_imu_accel, fuse_imu_angle, fuse_imu_rate, fuse_servos, fuse_wheels
from .config import imu_taken_s, mounting_covariance, string_covariance
from .consider import considered_columns
from .errors import EstimatorError
from .fast_cycle import fast_cycle
from .fast_imu import fast_imu
from .fast_manifold import fast_manifold
from .fast_prediction import fast_prediction
from .fusion import fuse
from .imu_latency import sample_lag_s, with_latency_columns
from .imu_model import ImuGeometry, euler_zyx
from .imu_prediction import predict_imu
from .layout import from_model_state, layout_of
from .manifold import Manifold
from .param_errors import ParamErrors
from .process_model import ProcessModel, check_model
from .servo_motion import step_input
from .timeouts import SourceMonitor

GOALS_KEPT = 64
"""Rest-length goals the filter remembers: at a goal a tick, 0.64 s, far more than a servo read
is ever behind the filter."""

SOURCES = (
    fuse_imu_rate.SOURCE,
    fuse_imu_accel.SOURCE,
    fuse_imu_angle.SOURCE,
    fuse_wheels.SOURCE,
    fuse_servos.SOURCE,
)
ROTATION_TOLERANCE = 1e-6
"""Largest entry of ``R^T R - I`` of the IMU's predicted axes taken as a rotation: their
frame is orthonormal to round-off (1e-15) wherever its nodes span a plane."""


class Status(IntFlag):
    """Fault bits of the filter (PX4 style): time-outs, last sample rejected, modes."""

    IMU_RATE_TIMEOUT = 1 << 0
    IMU_ACCEL_TIMEOUT = 1 << 1
    IMU_ANGLE_TIMEOUT = 1 << 2
    WHEELS_TIMEOUT = 1 << 3
    SERVOS_TIMEOUT = 1 << 4
    IMU_RATE_REJECTED = 1 << 5
    IMU_ACCEL_REJECTED = 1 << 6
    IMU_ANGLE_REJECTED = 1 << 7
    WHEELS_REJECTED = 1 << 8
    SERVOS_REJECTED = 1 << 9
    PREDICTION_ONLY = 1 << 10  # every source timed out: the estimate is the model's alone
    STALE_SAMPLE = 1 << 11  # the last sample was older than max_lag_s and was dropped

    @classmethod
    def timeout_bit(cls, source: str) -> "Status":
        return cls[f"{source.upper()}_TIMEOUT"]

    @classmethod
    def rejected_bit(cls, source: str) -> "Status":
        return cls[f"{source.upper()}_REJECTED"]


class _Filter(ExtendedKalmanFilter):
    """filterpy's EKF with the nonlinear state prediction supplied by the caller."""

    def predict_x(self, u=0):
        self.x = self.x_next


class TensegrityEKF:
    """EKF whose process model is the gyroscopic tensegrity dynamics of a scene.

    Parameters
    ----------
    model : gyrotensegrity.Model
    config : EstimatorConfig
    x0 : ndarray, shape (n,) or shorter, optional
        Initial estimate (default: the scene's initial state, zero bias); projected onto the
        constraints; the entries it leaves out (the mounting and wheel noise states) start at 0.
    P0 : ndarray, shape (n, n), optional
        Initial covariance (default: diagonal from the ``init_*_std`` keys).
    t0_s : float, s
    log : callable(Innovation), optional
        Receives every fusion attempt (accepted or rejected).
    fast : bool
        The compiled prediction step and IMU prediction (:mod:`.fast_prediction`,
        :mod:`.fast_imu`) where they cover the configuration, the compiled manifold
        (:mod:`.fast_manifold`) and the fusion without filterpy (:func:`.fusion.fuse`), an IMU
        sample's last step and fusion in one call (:mod:`.fast_cycle`); False: the reference
        path everywhere.
    """

    def __init__(self, model, config, x0=None, P0=None, t0_s=0.0, log=None, fast=True):
        check_model(model)
        self.model, self.config = model, config
        self.layout = L = layout_of(model, config)
        self.process = ProcessModel(model, config)
        self.fast = fast  # also the fusion's (:func:`.fusion.fuse`)
        self.fast_step = fast_prediction(self.process, L.size) if fast else None
        self.imu = ImuGeometry(model, config)
        self.params = ParamErrors(self.process, L) if L.params.stop > L.params.start else None
        self.considered = considered_columns(L, config.parameter_errors)
        self.manifold = (fast and fast_manifold(model, L)) or Manifold(model, L)
        self.position_columns = np.arange(L.q.start, L.q.stop)
        self.motion_columns = np.arange(L.q.start, L.q_dot.stop)
        self.dynamic_columns = np.arange(L.n_dynamic)
        # the columns the IMU prediction's Jacobians are over
        self.imu_columns = np.r_[self.dynamic_columns, L.mounting.start : L.mounting.stop]
        self.fast_imu = fast_imu(self)
        self.t = float(t0_s)
        self.t_start = self.t
        self.imu_lag_s = 0.0  # how far the filter was ahead of the last IMU sample, s
        self.u = model.input_at(self.t)
        # the rest-length goals in effect from each time on, newest last: a read sampled before
        # the filter's time is compared with the rest lengths taken back through them
        self.goal_history = deque([(self.t, self.u[: model.alpha].copy())], maxlen=GOALS_KEPT)
        self.log = log
        self.monitors = {s: SourceMonitor(s, _timeout(config, s)) for s in SOURCES}
        self.stale_last = False
        self._A = None  # linearisation of the dynamics at the current prior, if made
        # inputs not in effect yet, by due time: (s, "rest" or "wheels", values)
        self._commands: list[tuple[float, str, np.ndarray]] = []
        self.cycle = fast_cycle(self, ROTATION_TOLERANCE) if fast else None
        self.kf = _Filter(L.size, 1)
        if x0 is None:
            x0 = from_model_state(model, model.initial_state(), self.u)
        self.start_at(x0, P0)

    def start_at(self, x0, P0=None) -> None:
        """Set the state to ``x0`` (its leading entries; the mounting and wheel noise states
        after them 0: the configured mounting, no noise yet) with the covariance ``P0`` (n, n)
        (default :meth:`initial_covariance`), both conditioned on the constraint manifold."""
        x0 = np.concatenate([x0, np.zeros(self.layout.size - len(x0))])
        P0 = self.initial_covariance() if P0 is None else np.asarray(P0, float)
        x, P = self.manifold.condition(np.asarray(x0, float), P0)
        self.kf.x, self.kf.P = x.reshape(-1, 1), P

    def initial_covariance(self):
        """Diagonal initial covariance from the ``init_*_std`` keys, shape (n, n)."""
        L, c = self.layout, self.config
        std = np.empty(L.size)
        std[L.q] = c.init_position_std_m
        std[L.q_dot] = c.init_velocity_std_m_s
        std[L.omega] = c.init_wheel_std_rad_s
        std[L.rest] = c.init_rest_std_m
        std[L.bias] = c.init_gyro_bias_std_rad_s
        std[L.mounting] = 0.0
        std[L.accel_bias] = c.init_accel_bias_std_m_s2
        std[L.wheel_noise] = fuse_wheels.white_std(c)
        std[L.string_errors] = 0.0
        std[L.j3_error] = np.sqrt(c.j3_var_rel2)
        std[L.imu_latency] = c.imu_latency_std_s
        std[L.goal_delay] = c.servo_delay_std_s
        P = np.diag(std**2)
        if L.n_mounting:
            P[L.mounting, L.mounting] = mounting_covariance(c)
        if L.n_string_errors:
            P[L.string_errors, L.string_errors] = string_covariance(c)
        return P

    # -- state access ---------------------------------------------------------------------------
    @property
    def x(self):
        """Current estimate, shape (n,) (a view of filterpy's column)."""
        return self.kf.x[:, 0]

    @property
    def P(self):
        """Current covariance, shape (n, n)."""
        return self.kf.P

    def batch_nodes(self, X):
        """Node positions and velocities (K, 3, n) of a batch of filter states (K, n)."""
        L, K = self.layout, X.shape[0]
        q = X[:, L.q].reshape(K, 3, L.m)
        q_dot = X[:, L.q_dot].reshape(K, 3, L.m)
        dyn = self.process.dyn
        return dyn.N_fix + dyn.node_values(q), dyn.node_values(q_dot)

    def attitude(self):
        """Sensor axes in the world (3, 3) and Z-Y-X angles (3,) rad of the estimate (with its
        mounting, where that is a state)."""
        N, N_dot = self.batch_nodes(self.x[None, :])
        L = self.layout
        R_bs = self.imu.mounting(self.x[L.mounting])[0] if L.n_mounting else None
        R, _ = self.imu.frame(N, N_dot, R_bs)
        return R[0], euler_zyx(R)[0]

    @property
    def status(self) -> Status:
        """The status word: time-out and rejection bits of every source and the mode bits."""
        word = Status(0)
        for s, mon in self.monitors.items():
            if mon.timed_out:
                word |= Status.timeout_bit(s)
            if mon.last_rejected:
                word |= Status.rejected_bit(s)
        if all(mon.timed_out for mon in self.monitors.values()):
            word |= Status.PREDICTION_ONLY
        if self.stale_last:
            word |= Status.STALE_SAMPLE
        return word

    # -- time update ----------------------------------------------------------------------------
    def set_input(self, rest_length_m, t_s=None, wheel_speed_rad_s=None):
        """Commanded rest lengths (alpha,) m from ``t_s`` on (default: now; None: the previous
        ones), in effect ``servo_delay_s`` after it, held until the next command. A command
        ahead of the filter waits for the prediction to reach ``t_s`` (the run stamps a goal
        when it goes onto the bus; samples taken before that can still arrive), so samples
        fused meanwhile see the input they were taken under. With ``wheel_speed_rad_s``
        (n_w,), scene wheel order, the wheels' commanded spins too, in effect ``wheel_delay_s``
        after ``t_s`` (the wheel states follow them with ``wheel_lag_s``; none given: the
        previous ones; the first in effect at once)."""
        stamp = self.t if t_s is None else max(float(t_s), self.t)
        if rest_length_m is not None:
            self._queue(stamp + self.config.servo_delay_s, "rest", np.array(rest_length_m, float))
        if wheel_speed_rad_s is not None:
            speeds = np.array(wheel_speed_rad_s, float)
            if self.process.wheel_command_rad_s is None:
                self.process.command_wheels(speeds)
            elif not np.array_equal(speeds, self._newest_wheel_command()):
                # only changes: each queued command splits the prediction step at its due time
                self._queue(stamp + self.config.wheel_delay_s, "wheels", speeds)
        self._apply_due_commands()

    def _newest_wheel_command(self) -> np.ndarray:
        """The last wheel command given: the newest queued, else the one in effect."""
        queued = [values for _, kind, values in self._commands if kind == "wheels"]
        return queued[-1] if queued else self.process.wheel_command_rad_s

    def _queue(self, due_s: float, kind: str, values: np.ndarray) -> None:
        bisect.insort(self._commands, (due_s, kind, values), key=lambda c: c[0])

    def _apply_due_commands(self) -> float:
        """Put the commands due by now in effect; the next one's due time (inf: none
        pending)."""
        while self._commands and self._commands[0][0] <= self.t + 1e-12:
            due_s, kind, values = self._commands.pop(0)
            if kind == "wheels":
                self.process.command_wheels(values)
            else:
                self.process.goal_stepped(values - self.u[: self.model.alpha])
                self.u = self.u.copy()
                self.u[: self.model.alpha] = values
                self.goal_history.append((due_s, values))
        return self._commands[0][0] if self._commands else np.inf

    def advance(self, t_s: float, hold: bool = False) -> float:
        """Predict to ``t_s`` in steps of at most ``process_dt_s``; check the time-outs.

        With ``hold`` the last step, where no command falls due at its end, is left to the
        caller (:mod:`.fast_cycle`, which then checks the time-outs): its length is returned
        (0.0: none left).
        """
        dt_max = self.config.process_dt_s
        while t_s - self.t > 1e-12:
            due = self._apply_due_commands()
            dt = min(dt_max, t_s - self.t, max(due - self.t, 1e-9))
            if hold and t_s - (self.t + dt) <= 1e-12 and due > self.t + dt + 1e-12:
                return dt
            self.predict(dt)
        self._apply_due_commands()
        self.check_timeouts()
        return 0.0

    def check_timeouts(self) -> None:
        """Every source's time-out at the filter's time."""
        for mon in self.monitors.values():
            mon.check(self.t, self.t_start)

    def predict(self, dt: float) -> None:
        """One prediction step of ``dt`` s with the held input."""
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):  # checked below
            try:
                if self.fast_step is not None:
                    self._predict_fast(dt)
                else:
                    self._predict_reference(dt)
            except SimulationError as exc:  # the model's fast path refuses a singular state
                raise _failed(self.t + dt, f"prediction failed: {exc}", exc.member) from None
        self._A = None
        self.t += dt
        self._check_finite("prediction")
        # the state back onto the constraints (RK4 drifts ~1e-9 m per step); P keeps the
        # process noise in all directions until the next update projects it
        self.kf.x = self.manifold.project_state(self.x).reshape(-1, 1)

    def _predict_reference(self, dt: float) -> None:
        u = step_input(self, dt)
        x, x_next, F = self.x.copy(), *self.process.step(self.x, u, dt, self._A)
        self.kf.x_next = x_next.reshape(-1, 1)
        self.kf.F = F
        Q = self.process.noise(dt, F, self.x, self.P)
        self.kf.Q = np.zeros_like(F)  # the wheel noise states change at wheel samples only
        self.kf.Q[: len(Q), : len(Q)] = Q
        self.kf.predict()
        if self.params is not None:
            x_next, P = self.params.step(x, self.x, self.P, F, u, dt)
            self.kf.x, self.kf.P = x_next.reshape(-1, 1), P

    def _predict_fast(self, dt: float) -> None:
        """:meth:`_predict_reference`'s step in one kernel call (:mod:`.fast_prediction`)."""
        u = step_input(self, dt)
        x_next, P, F = self.fast_step(self.x, self.kf.P, u, dt, self._A)
        Q = self.process.noise(dt, None, self.x)  # the kinks' term is in P already
        P[: len(Q), : len(Q)] += Q
        if self.params is not None:
            x_next, P = self.params.step(self.x, x_next, P, F, u, dt)
        self.kf.x, self.kf.P = x_next.reshape(-1, 1), P

    def _check_finite(self, what: str) -> None:
        # a non-finite covariance entry reaches the diagonal within one step: the diagonal will do
        bad = np.flatnonzero(~np.isfinite(self.x) | ~np.isfinite(np.diag(self.P)))
        if bad.size:
            name = self.layout.labels()[bad[0]]
            raise _failed(self.t, f"{what} made state entry {name} non-finite", name)

    # -- measurement update ---------------------------------------------------------------------
    def constrain(self) -> None:
        """Condition estimate and covariance on the bar-length constraints (after an update)."""
        x, P = self.manifold.condition(self.x, self.P)
        self.kf.x, self.kf.P = x.reshape(-1, 1), P
        self._check_finite("update")

    def emit(self, result) -> None:
        if self.log is not None:
            self.log(result)

    def _arrive(self, t_s: float, source: str, hold: bool = False) -> float | None:
        """Bring the filter to a sample's time (with ``hold`` but its last step, whose length
        is returned: :meth:`advance`); None if the sample is too old to fuse."""
        if t_s >= self.t:
            held = self.advance(t_s, hold)
            self.stale_last = False
            return held
        self.monitors[source].out_of_order += 1
        self.stale_last = self.t - t_s > self.config.max_lag_s
        if self.stale_last:
            self.monitors[source].stale += 1
        return None if self.stale_last else 0.0

    def fuse_imu(self, t_s, omega_rad_s, accel_m_s2, euler_rad):
        """Predict to ``t_s`` and fuse one IMU sample: rate, specific force, angles.

        The three are linearised once (:func:`.imu_prediction.predict_imu`), gated each on its
        own NIS and the accepted ones fused in one update.

        ``t_s`` is the sample's stamp; it was taken ``imu_latency_s`` before
        (:func:`.config.imu_taken_s`). A sample taken before the filter's time (one that came after
        samples taken later, or after the run's tick predicted past it) is compared with the
        prediction taken back to its time along the dynamics (``h - lag dh/dt``).

        With the fast path's :mod:`.fast_cycle` the last prediction step and all of that are
        one kernel call; where it refuses, the stages from the same state.

        Returns
        -------
        list of Innovation (empty when the sample was stale)
        """
        taken_s = imu_taken_s(self.config, t_s)
        self.imu_lag_s = sample_lag_s(self, taken_s)
        held = self._arrive(taken_s, fuse_imu_rate.SOURCE, self.cycle is not None)
        if held is None:
            return []
        if self.cycle is not None:
            results = self.cycle(held, omega_rad_s, accel_m_s2, euler_rad)
            if results is not None:
                return results
            self.advance(taken_s)  # the held step the stages' way
        pred = self._imu_prediction()
        self._A = pred.A  # the lean process model's next linearisation
        if self.fast_imu is not None:
            made = self.fast_imu.measurements(pred, omega_rad_s, accel_m_s2, euler_rad)
        else:
            made = (
                fuse_imu_rate.measurement(self, pred, omega_rad_s),
                fuse_imu_accel.measurement(self, pred, accel_m_s2),
                fuse_imu_angle.measurement(self, pred, euler_rad),
            )
        return fuse(self, *with_latency_columns(self, pred, made))

    def _imu_prediction(self):
        """:func:`.imu_prediction.predict_imu` at the estimate, refused where the model refuses
        the state or the prediction is not finite: a finite state can still be one no IMU
        could see (bars folded together, nodes 1e150 m out after a diverging prediction), and
        the angle's rotation would fail on it."""
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):  # checked below
            try:
                if self.fast_imu is not None:
                    pred = self.fast_imu(self.x, self.u)
                else:
                    pred = predict_imu(self, self.x, self.u)
            except SimulationError as exc:
                raise _failed(self.t, f"the IMU's prediction failed: {exc}", exc.member) from None
        for name, value in vars(pred).items():
            if not np.all(np.isfinite(value)):
                what = f"the IMU's prediction ({name}) at the estimate is non-finite"
                raise _failed(self.t, what, name)
        off = float(np.max(np.abs(pred.R_ws.T @ pred.R_ws - np.eye(3))))
        if off > ROTATION_TOLERANCE:  # the frame's nodes overflowed or fell on one line
            what = (
                "the IMU's predicted axes at the estimate are not a rotation "
                f"(R^T R off the identity by {off:.3g})"
            )
            raise _failed(self.t, what, "R_ws")
        return pred

    def fuse_wheels(self, t_s, omega_rad_s):
        """Predict to ``t_s`` and fuse the wheel speeds (n_w,) rad/s."""
        if self._arrive(t_s, fuse_wheels.SOURCE) is None:
            return []
        return [fuse_wheels.fuse_wheels(self, omega_rad_s)]

    def fuse_servos(self, t_s, lengths_m, strings):
        """Predict to ``t_s`` and fuse string lengths (k,) m of model strings ``strings``
        (sampled at ``t_s``: a read behind the filter's time is compared with the rest lengths
        then)."""
        lag_s = max(self.t - t_s, 0.0)
        if self._arrive(t_s, fuse_servos.SOURCE) is None:
            return []
        return [fuse_servos.fuse_servos(self, lengths_m, strings, lag_s)]


def _timeout(config, source: str) -> float:
    """The time-out of ``source``, s."""
    if source.startswith("imu"):
        return config.imu_timeout_s
    return config.wheels_timeout_s if source == "wheels" else config.servos_timeout_s


def _failed(t_s: float, what: str, member: str) -> EstimatorError:
    """The filter's error at ``t_s``: ``t = ... s: what``, naming ``member``."""
    return EstimatorError(f"t = {t_s:.6g} s: {what}", t_s, member)
