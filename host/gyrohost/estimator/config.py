"""Estimator configuration: noise, gates, time-outs, process model; every default here.

The keys (one flat table, ``[estimator]`` in a TOML file or a dict) are documented in
``docs/estimator.md``. Unknown keys, wrong types and out-of-range values raise
:class:`EstimatorConfigError` naming the key.
"""

import math
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

from gyrohost.config import IMU_FRAME_NODES
from gyrohost.drivers import wheelproto as wp
from gyrotensegrity.textfile import read_toml

from .errors import EstimatorConfigError

_DEG = math.pi / 180.0


def speed_filter_delay_s(shift: int) -> float:
    """How far the wheel board's reported speed trails the wheel's own while it changes
    steadily, s: the firmware's low-pass ``y += (x - y) / 2^shift`` per tick trails a ramp by
    ``2^shift - 1`` ticks, and its input, the encoder's count difference over the last tick, is
    that tick's mean speed, half a tick behind the tick's end."""
    return (2**shift - 0.5) / wp.TICK_HZ


SPEED_FILTER_DELAY_S = speed_filter_delay_s(wp.PARAM_BY_NAME["SPEED_FILTER_SHIFT"].default)
"""The delay of the firmware's default SPEED_FILTER_SHIFT (3): 7.5 ms."""


def _pos(doc: str, lo: float = 0.0, hi: float = math.inf) -> dict:
    return {"lo": lo, "hi": hi, "doc": doc}


# The largest figure each kind of key can mean. A standard deviation beyond its sensor's full
# scale, or a rig's size, says nothing a smaller one would not; a typo of that size (1e300)
# would overflow the covariances after the wheels spun up. The run refuses it before.
RATE_FULL_SCALE_RAD_S = math.radians(2000.0)
"""The BWT61CL's gyro range, +-2000 deg/s."""
ACCEL_FULL_SCALE_M_S2 = 16.0 * 9.80665
"""The BWT61CL's accelerometer range, +-16 g."""
WHEEL_FULL_SCALE_RAD_S = 400.0
"""The largest SPEED_MAX the wheel board takes (400,000 mrad/s)."""
RIG_SIZE_M = 10.0
"""The longest string a servo may wind (``[[servos.servo]] max_length_m``'s maximum)."""
PSD_MAX = 1.0e4
"""The largest white-noise density of any process noise key: a walk that carries a state a
hundred of its units away within a second (m, rad/s) means the model no longer predicts it."""


def _std(doc: str, hi: float) -> dict:
    """A standard deviation, at most ``hi`` (its sensor's full scale or the rig's size)."""
    return _pos(doc, 0.0, hi)


def _psd(doc: str) -> dict:
    return _pos(doc, 0.0, PSD_MAX)


@dataclass(frozen=True)
class EstimatorConfig:
    """All settings of the EKF. Units are in the names; see docs/estimator.md."""

    # measurement noise (standard deviations, white), per component
    imu_rate_std_rad_s: float = field(
        default=1.0e-3, metadata=_std("gyro noise", RATE_FULL_SCALE_RAD_S)
    )
    imu_accel_std_m_s2: float = field(
        default=0.03, metadata=_std("accelerometer noise", ACCEL_FULL_SCALE_M_S2)
    )
    imu_angle_std_rad: float = field(
        default=0.06 * _DEG, metadata=_std("Euler angle noise", math.pi)
    )
    wheel_speed_std_rad_s: float = field(
        default=0.5, metadata=_std("wheel speed noise", WHEEL_FULL_SCALE_RAD_S)
    )
    # the wheel telemetry's noise from one sample to the next as MA(1), v_k = a_k + theta a_{k-1}
    # (a_k white; the a of the last sample is a state, one per wheel); 0: white
    wheel_noise_ma1: float = field(default=0.0, metadata=_pos("wheel noise MA(1)", -0.99, 0.99))
    servo_length_std_m: float = field(default=2.0e-4, metadata=_std("servo noise", RIG_SIZE_M))
    # how far a read's position is off the rest length the strings pull with while the servo
    # moves, as time: adds (d rest/dt)^2 servo_time_std_s^2 to the servo noise, s
    servo_time_std_s: float = field(default=0.0, metadata=_pos("servo read time std", 0.0, 0.1))
    # process noise (white, spectral densities)
    accel_psd_m2_s3: float = field(default=1.0e-4, metadata=_psd("node acceleration noise"))
    wheel_accel_psd_rad2_s3: float = field(default=1.0, metadata=_psd("wheel spin noise"))
    rest_psd_m2_s: float = field(default=1.0e-6, metadata=_psd("rest length walk"))
    # a resting servo's string sits anywhere within this spread of its command (the goal's
    # count, where the servo stops about it): a walk of the rest lengths that keeps it as their
    # spread through the lag, whatever the step, m
    rest_hold_std_m: float = field(default=0.0, metadata=_std("resting servo spread", RIG_SIZE_M))
    # a goal step's spread about the first-order lag, std ratio x |goal step|, kept about the
    # lag until the next goal: a goal taken at an uncertain time (time std / lag), or a servo
    # that covers each goal step at its moving speed and holds (1/sqrt(12)); 0: none
    servo_step_std_ratio: float = field(default=0.0, metadata=_pos("servo in-step std", 0.0, 10.0))
    # white noise of the rest lengths as the string forces see them (the servo's motion within a
    # step, pulley compliance): acts on the nodes only through taut strings, m^2 s
    rest_jitter_psd_m2_s: float = field(default=0.0, metadata=_psd("rest length jitter"))
    gyro_bias_psd_rad2_s3: float = field(default=1.0e-10, metadata=_psd("gyro bias walk"))
    # initial uncertainty
    init_position_std_m: float = field(
        default=2.0e-3, metadata=_std("initial node position", RIG_SIZE_M)
    )
    init_velocity_std_m_s: float = field(
        default=5.0e-3, metadata=_std("initial node velocity", RIG_SIZE_M)
    )
    init_wheel_std_rad_s: float = field(
        default=2.0, metadata=_std("initial wheel speed", WHEEL_FULL_SCALE_RAD_S)
    )
    init_rest_std_m: float = field(default=1.0e-3, metadata=_std("initial rest length", RIG_SIZE_M))
    init_gyro_bias_std_rad_s: float = field(
        default=0.5 * _DEG, metadata=_std("initial bias", RATE_FULL_SCALE_RAD_S)
    )
    # the accelerometer's bias: 0 folds it into imu_accel_std_m_s2 (white noise it is not: it
    # stays for the run); above 0 it is a state with this prior and walks by its density
    init_accel_bias_std_m_s2: float = field(
        default=0.0, metadata=_std("initial accelerometer bias", ACCEL_FULL_SCALE_M_S2)
    )
    accel_bias_psd_m2_s5: float = field(default=0.0, metadata=_psd("accelerometer bias walk"))
    # gates: NIS thresholds as chi-square probabilities; time-outs
    gate_probability: float = field(default=0.9999, metadata=_pos("NIS gate", 0.5, 1.0))
    imu_timeout_s: float = field(default=0.1, metadata=_pos("IMU time-out", 1e-3))
    wheels_timeout_s: float = field(default=0.2, metadata=_pos("wheel time-out", 1e-3))
    servos_timeout_s: float = field(default=0.5, metadata=_pos("servo time-out", 1e-3))
    max_lag_s: float = field(default=0.05, metadata=_pos("oldest sample fused", 0.0))
    # IMU sample times from arrival stamps (replay): period (0 = keep stamps), largest delay
    imu_period_s: float = field(default=0.01, metadata=_pos("IMU output period", 0.0, 1.0))
    imu_max_delay_s: float = field(default=0.03, metadata=_pos("IMU arrival delay", 0.0, 1.0))
    # how far a sample's reconstructed time may be off its true one (latency, the grid's
    # residual jitter): adds (dh/dt)^2 imu_time_std_s^2 to each IMU source's noise, s
    imu_time_std_s: float = field(default=0.0, metadata=_pos("IMU sample time std", 0.0, 0.1))
    # the IMU's smallest delay from sampling to the host's stamp (transfer, the reader's
    # wake-up): a reconstructed grid time is that much after the sample was taken, s
    imu_latency_s: float = field(default=0.0, metadata=_pos("IMU latency", 0.0, 0.1))
    # how well imu_latency_s is known (1-sigma, e.g. from gyrotens identify): nonzero makes its
    # error a state, the same for the whole run (gyrohost.estimator.imu_latency), s
    imu_latency_std_s: float = field(default=0.0, metadata=_pos("IMU latency std", 0.0, 0.1))
    # process model
    process_dt_s: float = field(default=0.01, metadata=_pos("largest predict step", 1e-4, 0.1))
    process_method: str = field(default="lean", metadata={"choices": ("lean", "rk4")})
    # A = df/dx of the dynamics (and the IMU fusion's Jacobians through it): "analytic" (closed
    # form, compiled: gyrotensegrity.fast_jacobian) or "complex-step" (one batched complex
    # evaluation); the same to round-off, the closed form cheaper (docs/estimator.md)
    jacobian: str = field(default="analytic", metadata={"choices": ("analytic", "complex-step")})
    rk4_substep_s: float = field(default=1.0e-3, metadata=_pos("rk4 substep", 1e-5, 0.1))
    servo_lag_s: float = field(default=0.05, metadata=_pos("servo response time", 1e-3, 10.0))
    # a goal reaches the servos this long after its stamp (the bus and the servo taking it up;
    # gyrotens identify fits it with the lag), s
    servo_delay_s: float = field(default=0.0, metadata=_pos("servo goal delay", 0.0, 0.1))
    # how well servo_delay_s holds for a run: a run's delay is where the phase of its ticks puts
    # its goals in the rig's latency spread, fixed for the run; nonzero makes its error a state
    # (gyrohost.estimator.param_errors), zero takes the delay as exact
    servo_delay_std_s: float = field(default=0.0, metadata=_pos("servo goal delay std", 0.0, 0.1))
    # the servos close a goal step at most at this string speed (their moving speed), by the
    # lag within it (gyrohost.drivers.mx12.lag_error_after); unset: the lag alone
    servo_speed_m_s: float = field(default=math.inf, metadata=_pos("servo speed limit", 1e-4))
    # the wheels follow the commanded speeds (set_input's wheel_speed_rad_s) through this lag,
    # at most at the board's ramp rate (ACCEL_RAD_S2); 0: the speeds are held (the model's input)
    wheel_lag_s: float = field(default=0.0, metadata=_pos("wheel response time", 0.0, 10.0))
    wheel_accel_rad_s2: float = field(default=100.0, metadata=_pos("wheel ramp rate", 1e-3))
    # the board reports its speed through a low-pass, which trails a changing speed by this
    # much: a telemetry sample reads omega - wheel_filter_s d omega/dt (the wheel states are the
    # wheels' own speeds, which drive the structure), s
    wheel_filter_s: float = field(default=0.0, metadata=_pos("wheel speed filter delay", 0.0, 1.0))
    # from a wheel command's time stamp to when the wheels are seen to follow it (the command's
    # way to the board, the telemetry's way back), s
    wheel_delay_s: float = field(default=0.0, metadata=_pos("wheel command delay", 0.0, 1.0))
    # how far the time the board acts on a command may be off the command's stamp plus
    # wheel_delay_s: while a wheel changes speed its state walks so that its spread reaches
    # (wheel_command_time_std_s d omega/dt)^2, s
    wheel_command_time_std_s: float = field(
        default=0.0, metadata=_pos("wheel command time std", 0.0, 0.1)
    )
    # how far a telemetry frame's arrival stamp may be off its sample time: adds
    # (d omega/dt)^2 wheel_time_std_s^2 to the wheel noise while the wheels change speed, s
    wheel_time_std_s: float = field(default=0.0, metadata=_pos("wheel stamp std", 0.0, 0.1))
    # when the wheel board's samples were taken: "device", its own clock (t_us) put on the
    # host's (driver.DeviceClock); "arrival", as the host stamped them
    wheel_times: str = field(default="device", metadata={"choices": ("device", "arrival")})
    # a telemetry frame's time on the wire, s: the device clock puts a sample at its board
    # time plus the shortest delay the frames arrived with, less this (its bits at the link's
    # baud, which no frame arrives sooner than); rig_keys derives it from [wheelboard] baud
    wheel_wire_s: float = field(default=0.0, metadata=_pos("wheel telemetry wire time", 0.0, 0.1))
    # the wheel board's wire resolution (SET_SPEEDS and telemetry in integer mrad/s): the board
    # spins to each command rounded to it, and its telemetry truncates towards zero (a reading
    # low in magnitude by half of it on average); 0: both exact, rad/s
    wheel_resolution_rad_s: float = field(default=0.0, metadata=_pos("wheel wire step", 0.0, 1.0))
    # the string kink the prediction uses: "sharp" (tension-only, as the model) or "mean" (the
    # expected force under the rest-length jitter, rest_jitter_psd_m2_s; the jitter noise then
    # carries only its variance about that mean)
    kink_model: str = field(default="sharp", metadata={"choices": ("sharp", "mean")})
    # where the wheels' motor reaction goes (gyrohost.control.wheel_reaction): "lost", the
    # paper's model (bars that carry no torque about their axis); "body", the hinged rig's,
    # whose hinges pass it on and turn the whole structure (the filter: .motor_reaction)
    wheel_reaction: str = field(default="lost", metadata={"choices": ("lost", "body")})
    # IMU attachment (as the rig's truth, gyrohost.simrig.truth): body frame from three scene
    # nodes (the rig's default: the D-bar's), sensor axes turned by mounting_rpy, gravity the
    # sensor feels (world frame)
    imu_frame_nodes: tuple[str, str, str] = IMU_FRAME_NODES
    imu_mounting_rpy_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)
    # how well imu_mounting_rpy_rad is known (1-sigma of roll, pitch, yaw, or their full
    # covariance, e.g. from gyrotens identify): nonzero makes the error of the three angles a
    # state (:func:`mounting_covariance`); zero takes the mounting as exact
    imu_mounting_std_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)
    imu_mounting_cov_rad2: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 0.0),) * 3
    # how well the scene's string stiffness and damping are known (covariance of their log
    # factors, e.g. from gyrotens identify): nonzero makes their errors states
    # (gyrohost.estimator.param_errors); zero takes the scene's as exact
    string_cov_rel2: tuple[tuple[float, float], ...] = ((0.0, 0.0),) * 2
    # how well the scene's wheel J3 is known (the variance of its log factor, one for every
    # wheel, e.g. from gyrotens identify): nonzero makes its error a state; zero takes it exact
    j3_var_rel2: float = field(default=0.0, metadata=_pos("J3 variance", 0.0, 1.0))
    # the errors above, the IMU latency's and the goal delay's, where states: "considered" keeps
    # them at their prior and carries their covariance (a run's seconds cannot learn them, its
    # transients would land in them: gyrohost.estimator.consider); "estimated" updates them
    parameter_errors: str = field(
        default="considered", metadata={"choices": ("considered", "estimated")}
    )
    imu_gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.80665)


def config_from_dict(data: dict, source: str = "<dict>") -> EstimatorConfig:
    """Build an :class:`EstimatorConfig` from a flat table; ``source`` names it in errors."""
    if not isinstance(data, dict):
        raise EstimatorConfigError(
            f"{source}: the estimator's keys must be a table, got {type(data).__name__} {data!r}"
        )
    known = {f.name: f for f in fields(EstimatorConfig)}
    values = {}
    for key, value in data.items():
        if key not in known:
            raise EstimatorConfigError(
                f"{source}: unknown estimator key '{key}' (known: {', '.join(sorted(known))})"
            )
        values[key] = _check(known[key], value, f"{source}: estimator key '{key}'")
    config = replace(EstimatorConfig(), **values)
    _check_uncertainties(config, source)
    if config.imu_period_s > 0.0 and config.imu_latency_s > config.imu_max_delay_s:
        raise EstimatorConfigError(
            f"{source}: estimator key 'imu_latency_s' = {config.imu_latency_s} s exceeds "
            f"'imu_max_delay_s' = {config.imu_max_delay_s} s: the host places a sample at most "
            "that long before its arrival; raise imu_max_delay_s above the latency"
        )
    if len(set(config.imu_frame_nodes)) != 3:
        raise EstimatorConfigError(
            f"{source}: estimator key 'imu_frame_nodes' names {list(config.imu_frame_nodes)}: "
            "three different nodes make a frame"
        )
    return config


def mounting_covariance(config: EstimatorConfig):
    """Prior covariance (3, 3), rad^2, of the error of the configured mounting's roll, pitch and
    yaw: ``imu_mounting_cov_rad2``, else ``diag(imu_mounting_std_rad^2)``; None when both are
    zero (the mounting taken as exact, no mounting state)."""
    import numpy as np

    cov = np.array(config.imu_mounting_cov_rad2, float)
    if not cov.any():
        cov = np.diag(np.square(config.imu_mounting_std_rad))
    return cov if cov.any() else None


def string_covariance(config: EstimatorConfig):
    """Prior covariance (2, 2) of the errors of the scene's string stiffness and damping (log
    factors): ``string_cov_rel2``; None when zero (the scene's taken as exact, no state)."""
    import numpy as np

    cov = np.array(config.string_cov_rel2, float)
    return cov if cov.any() else None


def _check_uncertainties(config: EstimatorConfig, source: str) -> None:
    """The mounting's and the strings' uncertainties: stds not negative, a covariance
    symmetric and positive semi-definite, not both given for the mounting."""
    import numpy as np

    std, cov = np.array(config.imu_mounting_std_rad), np.array(config.imu_mounting_cov_rad2)
    where = f"{source}: estimator key"
    if np.any(std < 0.0):
        raise EstimatorConfigError(f"{where} 'imu_mounting_std_rad' must not be negative")
    if std.any() and cov.any():
        raise EstimatorConfigError(
            f"{where}s 'imu_mounting_std_rad' and 'imu_mounting_cov_rad2': give one of them"
        )
    _check_covariance(cov, f"{where} 'imu_mounting_cov_rad2'")
    _check_covariance(np.array(config.string_cov_rel2), f"{where} 'string_cov_rel2'")


def _check_covariance(cov, where: str) -> None:
    import numpy as np

    if not np.allclose(cov, cov.T, rtol=1e-9, atol=0.0):
        raise EstimatorConfigError(f"{where} must be symmetric")
    if np.linalg.eigvalsh(cov).min() < -1e-12 * max(np.abs(cov).max(), 1e-300):
        raise EstimatorConfigError(f"{where} must be positive semi-definite")


def load_config(path: str | Path) -> EstimatorConfig:
    """Read the ``[estimator]`` table of a TOML file (the whole file if it has no such table)."""
    return config_from_dict(read_table(path), str(path))


def read_table(path: str | Path) -> dict:
    """The ``[estimator]`` table of a TOML file (the whole file if it has no such table)."""
    data = read_toml(path, EstimatorConfigError)
    table = data.get("estimator", data)
    if not isinstance(table, dict):
        raise EstimatorConfigError(
            f"{path}: key 'estimator' must be a table, got {type(table).__name__} {table!r}"
        )
    return table


def for_rig(rig, path: str | Path | None = None) -> EstimatorConfig:
    """The EKF's configuration for a run on ``rig`` (a ``gyrohost.config.RigConfig``).

    Layers, each overriding the keys it names: the defaults; the IMU's output period, time-out
    and mounting from ``[imu]`` and the servos' speed limit from ``[servos]``
    (:func:`rig_keys`); the rig's ``[estimator]`` keys; the ``[estimator]`` table of the file
    ``path`` (``gyrotens run --estimator``).

    Raises
    ------
    EstimatorConfigError
        An unknown key or bad value, naming the file and the key.
    """
    return config_from_dict({**rig_keys(rig), **rig_overrides(rig, path)}, rig.source)


def rig_overrides(rig, path: str | Path | None = None) -> dict:
    """The keys of the rig's ``[estimator]`` table, then those of the ``[estimator]`` table of
    the file ``path`` over them: the last layers of :func:`for_rig` (and of the in-process SIL,
    over its own keys). Each table is checked on its own, so that an error names its file.

    Raises
    ------
    EstimatorConfigError
        An unknown key or bad value, naming the file and the key.
    """
    keys = dict(rig.estimator)
    config_from_dict(keys, f"{rig.source}: [estimator]")
    return {**keys, **file_keys(path)}


def file_keys(path: str | Path | None) -> dict:
    """The keys of the ``[estimator]`` table of the file ``path`` (none for ``None``), checked.

    Raises
    ------
    EstimatorConfigError
        The file is missing or not TOML, or a key is unknown or bad (naming the file).
    """
    if path is None:
        return {}
    keys = read_table(path)
    config_from_dict(keys, str(path))
    return keys


def _check(f, value, where: str):
    default = f.default
    if isinstance(default, tuple):
        return _check_array(default, value, where)
    if isinstance(default, str):
        if value not in f.metadata["choices"]:
            raise EstimatorConfigError(f"{where} is {value!r}, one of {f.metadata['choices']}")
        return value
    if value == default and not isinstance(value, bool):  # an infinite default reads back
        return float(value)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise EstimatorConfigError(f"{where} must be a finite number, got {value!r}")
    lo, hi = f.metadata["lo"], f.metadata["hi"]
    if not lo <= value <= hi:
        raise EstimatorConfigError(f"{where} is {value}, must be in [{lo}, {hi}]")
    return float(value)


def _check_array(default: tuple, value, where: str) -> tuple:
    """An array like ``default`` (of str or float, or of such arrays: a matrix)."""
    if not isinstance(value, list | tuple) or len(value) != len(default):
        shape = [list(d) if isinstance(d, tuple) else d for d in default]
        raise EstimatorConfigError(f"{where} must be an array like {shape}")
    if isinstance(default[0], tuple):
        return tuple(_check_array(d, v, where) for d, v in zip(default, value, strict=True))
    kind = type(default[0])
    ok = all(isinstance(v, kind) or kind is float and type(v) is int for v in value)
    if not ok or kind is float and not all(math.isfinite(v) for v in value):
        raise EstimatorConfigError(f"{where} must hold finite {kind.__name__} values")
    return tuple(kind(v) for v in value)


def rig_keys(rig) -> dict:
    """Keys a rig configuration's device tables fix: the IMU's output period, time-out and
    mounting (``[imu]``); the wheel board's telemetry frame's time on the wire at its baud
    (``[wheelboard]``); the servos' speed limit, the moving speed the driver writes with every
    goal (``[servos.servo] max_speed_m_s``; one limit in the filter: the slowest's)."""
    keys = {
        "wheel_wire_s": wp.wire_time_s("TELEMETRY", rig.wheelboard.baud),
        "imu_timeout_s": rig.imu.timeout_s,
        "imu_period_s": 1.0 / rig.imu.rate_hz,
        "imu_mounting_rpy_rad": tuple(rig.imu.mounting_rpy_rad),
    }
    if any(s.string for s in rig.servos.servo):
        keys["servo_speed_m_s"] = servo_speed_m_s(rig)
    return keys


def servo_speed_m_s(rig) -> float:
    """The string speed the servos of ``rig`` close a goal step at most at: the moving speed
    the driver writes with every goal, ``max_speed_m_s``, the slowest wound servo's (inf:
    none winds a string)."""
    return min((s.max_speed_m_s for s in rig.servos.servo if s.string), default=math.inf)


def imu_taken_s(config: EstimatorConfig, t_s: float) -> float:
    """When an IMU sample stamped ``t_s`` (s) was taken: ``imu_latency_s`` before."""
    return t_s - config.imu_latency_s


MIN_WHEEL_WALK = 1e-6
"""The wheels' walk (rad^2/s^3) the filter keeps for wheels measured or emulated without a
speed error: with none the wheel covariance collapses, and the in-process SIL diverged on the
identification's truth (NEES 3e5 for 28)."""

EXACT_IMU_TIMES = {"imu_latency_s": 0.0, "imu_time_std_s": 0.0}
"""Keys for IMU samples that carry their own times (in-process runs): no latency, no
uncertainty about it (a real-time rig's configuration gives both)."""


def servo_hold_std(count_m, band_steps):
    """``rest_hold_std_m``, m: a resting servo's string sits off its command by the goal's
    rounding to a count (uniform over one) and by where the servo stopped within its hold band
    (uniform over ``+-band_steps`` counts), variance ``count^2 (1 + 4 band^2) / 12``.

    Parameters
    ----------
    count_m : float
        The string length of one servo step, m.
    band_steps : float
        The servos' hold band, steps (``[sim.servos] hold_band_steps``).
    """
    return count_m * math.sqrt((1.0 + 4.0 * band_steps**2) / 12.0)


def imu_wire_counts() -> tuple[float, float, float]:
    """One count of the IMU's wire format: rate (rad/s), specific force (m/s^2), angle (rad)."""
    from gyrohost.drivers.imu import ACCEL_SCALE_M_S2, ANGLE_SCALE_RAD, RATE_SCALE_RAD_S

    return float(RATE_SCALE_RAD_S), float(ACCEL_SCALE_M_S2), float(ANGLE_SCALE_RAD)
