"""The filter's state vector and its relation to the model's state.

Filter state ``x`` (flat, float64, size ``6 m + n_w + alpha + 3``, 3 more with the IMU
mounting's error as a state, 3 more with the accelerometer's bias as a state and ``n_w`` more
with the wheel telemetry's noise as a state)::

    x = [ vec(eta2) (3 m, m) | vec(eta2_dot) (3 m, m/s) | omega_w (n_w, rad/s)
          | rest (alpha, m) | b_g (3, rad/s) | d_mount (3, rad, optional)
          | b_a (3, m/s^2, optional) | a_w (n_w, rad/s, optional)
          | d_strings (2, optional) | d_J3 (1, optional) | d_lat (1, s, optional)
          | d_goal (1, s, optional) ]

``eta2`` are the model's independent node coordinates (row by row, as in
:mod:`gyrotensegrity.model`), ``omega_w`` the spin of every wheel about ``+b``, ``rest`` the
string rest lengths the servos have actually reached (they lag the command), ``b_g`` the gyro
bias in sensor axes, ``d_mount`` the error of the configured mounting's roll, pitch and yaw (the
true angles less ``imu_mounting_rpy_rad``; a random constant, present when the configuration
gives the mounting an uncertainty: :func:`.config.mounting_covariance`), ``b_a`` the
accelerometer's bias in sensor axes (a random constant, present when the configuration gives it
a prior: ``init_accel_bias_std_m_s2``), ``a_w`` the white term
of the last wheel sample's noise, which the next sample's noise shares (``wheel_noise_ma1``,
:mod:`.fuse_wheels`), ``d_strings`` the errors of the strings' stiffness and damping (relative:
log factors on the scene's), ``d_J3`` that of the wheels' J3 (a log factor on every wheel's),
``d_lat`` that of the IMU's latency (:mod:`.imu_latency`) and ``d_goal`` the error of the
servos' goal delay
(``servo_delay_s``), random constants present when the configuration gives them an
uncertainty (:mod:`.param_errors`). Wheel angles are left out (nothing observes them,
nothing depends on them).
"""

from dataclasses import dataclass

import numpy as np

from .config import mounting_covariance, string_covariance


@dataclass(frozen=True)
class FilterLayout:
    """Sizes and slices of the filter state."""

    m: int
    n_wheels: int
    n_strings: int
    n_wheel_noise: int = 0  # n_wheels with the wheel noise as a state, else 0
    n_mounting: int = 0  # 3 with the mounting's error as a state, else 0
    n_accel_bias: int = 0  # 3 with the accelerometer's bias as a state, else 0
    n_string_errors: int = 0  # 2 with the strings' stiffness and damping errors, else 0
    n_goal_delay: int = 0  # 1 with the servos' goal delay error as a state, else 0
    n_j3_error: int = 0  # 1 with the wheels' J3 error as a state, else 0
    n_imu_latency: int = 0  # 1 with the IMU latency's error as a state, else 0

    @property
    def size(self) -> int:
        n_params = self.n_string_errors + self.n_j3_error + self.n_imu_latency + self.n_goal_delay
        return self.n_base + self.n_wheel_noise + n_params

    @property
    def n_base(self) -> int:
        """Entries of the model's state, the gyro bias, the mounting's error and the
        accelerometer's bias (all but the wheel noise states: those a truth can give)."""
        return self.n_dynamic + 3 + self.n_mounting + self.n_accel_bias

    @property
    def n_dynamic(self) -> int:
        """Entries the dynamics act on (all but the gyro bias)."""
        return 6 * self.m + self.n_wheels + self.n_strings

    @property
    def q(self) -> slice:
        return slice(0, 3 * self.m)

    @property
    def q_dot(self) -> slice:
        return slice(3 * self.m, 6 * self.m)

    @property
    def omega(self) -> slice:
        return slice(6 * self.m, 6 * self.m + self.n_wheels)

    @property
    def rest(self) -> slice:
        return slice(6 * self.m + self.n_wheels, self.n_dynamic)

    @property
    def bias(self) -> slice:
        return slice(self.n_dynamic, self.n_dynamic + 3)

    @property
    def mounting(self) -> slice:
        return slice(self.n_dynamic + 3, self.n_dynamic + 3 + self.n_mounting)

    @property
    def accel_bias(self) -> slice:
        return slice(self.mounting.stop, self.n_base)

    @property
    def wheel_noise(self) -> slice:
        return slice(self.n_base, self.n_base + self.n_wheel_noise)

    @property
    def string_errors(self) -> slice:
        return slice(self.wheel_noise.stop, self.wheel_noise.stop + self.n_string_errors)

    @property
    def j3_error(self) -> slice:
        return slice(self.string_errors.stop, self.string_errors.stop + self.n_j3_error)

    @property
    def imu_latency(self) -> slice:
        return slice(self.j3_error.stop, self.j3_error.stop + self.n_imu_latency)

    @property
    def goal_delay(self) -> slice:
        return slice(self.imu_latency.stop, self.size)

    @property
    def params(self) -> slice:
        """The identified parameters' errors: the strings', J3's, the IMU latency's and the
        goal delay's."""
        return slice(self.wheel_noise.stop, self.size)

    def labels(self) -> list[str]:
        """Column names of the state entries, with units."""
        names = [f"q_{a}{j}_m" for a in "xyz" for j in range(self.m)]
        names += [f"qdot_{a}{j}_m_s" for a in "xyz" for j in range(self.m)]
        names += [f"omega_w{k}_rad_s" for k in range(self.n_wheels)]
        names += [f"rest{k}_m" for k in range(self.n_strings)]
        names += [f"gyro_bias_{a}_rad_s" for a in "xyz"]
        names += [f"mounting_{a}_rad" for a in ("roll", "pitch", "yaw")[: self.n_mounting]]
        names += [f"accel_bias_{a}_m_s2" for a in "xyz"[: self.n_accel_bias]]
        names += [f"wheel_noise{k}_rad_s" for k in range(self.n_wheel_noise)]
        names += ["stiffness_error", "damping_error"][: self.n_string_errors]
        names += ["j3_error"][: self.n_j3_error]
        names += ["imu_latency_error_s"][: self.n_imu_latency]
        return names + ["goal_delay_error_s"][: self.n_goal_delay]


def layout_of(model, config=None) -> FilterLayout:
    """The filter state's layout for ``model``; with ``config`` (EstimatorConfig) the wheel
    noise and mounting states it asks for."""
    n_w = len(model.wheel_bars)
    if config is None:
        return FilterLayout(model.m, n_w, model.alpha)
    noise = n_w if config.wheel_noise_ma1 != 0.0 else 0
    mounting = 3 if mounting_covariance(config) is not None else 0
    accel_bias = 3 if config.init_accel_bias_std_m_s2 > 0.0 else 0
    strings = 2 if string_covariance(config) is not None else 0
    goal = 1 if config.servo_delay_std_s > 0.0 else 0
    j3 = 1 if config.j3_var_rel2 > 0.0 else 0
    latency = 1 if config.imu_latency_std_s > 0.0 else 0
    return FilterLayout(
        model.m,
        n_w,
        model.alpha,
        n_wheel_noise=noise,
        n_mounting=mounting,
        n_accel_bias=accel_bias,
        n_string_errors=strings,
        n_goal_delay=goal,
        n_j3_error=j3,
        n_imu_latency=latency,
    )


def from_model_state(model, x_model, u, gyro_bias=(0.0, 0.0, 0.0)):
    """Filter state of a model state ``x_model`` under input ``u`` (wheel speeds from either,
    rest lengths from ``u``)."""
    L = model.layout
    return np.concatenate(
        [
            x_model[L.q],
            x_model[L.q_dot],
            model.wheel_speeds(x_model, u),
            np.asarray(u, float)[: model.alpha],
            np.asarray(gyro_bias, float),
        ]
    )
