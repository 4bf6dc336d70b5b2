"""The forward model of identification: the rig's truth model driven by a log's inputs.

A recording's servo positions (``servos`` stream, plus each servo's zero offset) become the
wound strings' rest lengths (through the string lag ``servo_lag_s``), its wheel speeds
(``wheels`` stream) the wheels' spins; the model (:class:`gyrohost.simrig.truth.Truth`: the fast
path, speed-controlled wheels) is stepped from the scene's initial state at the log's first IMU
sample, and the IMU frame's rate, specific force and attitude are read at every step and
interpolated to the IMU's time stamps. :func:`sensor_outputs` turns them into what the IMU
reports: rotated into the sensor's axes by the mounting rotation, plus the biases;
:func:`output_error` compares them with the recording (the attitude as its tilt).
"""

from dataclasses import dataclass, field, replace

import numpy as np

from gyrohost.config import IMU_FRAME_NODES, RigConfig
from gyrohost.estimator import streams
from gyrohost.estimator.config import servo_speed_m_s
from gyrohost.estimator.fuse_imu_angle import FLOOR
from gyrohost.estimator.servo_motion import lagged
from gyrohost.geometry import levelling_rotvec, rotation_zyx
from gyrohost.ident import shooting
from gyrohost.ident.servo_render import ServoResponse, rendered
from gyrohost.simrig.config import TruthConfig
from gyrohost.simrig.truth import Truth, torque_driven
from gyrotensegrity import Scene

from .errors import IdentDataError

STEP_S = 0.005
"""The forward model's step, s. Its inputs move in a straight line over each step between their
values at its ends (:meth:`Truth.step`), as a real rig's strings and wheels move smoothly; 5 ms
is a tenth of their servos' lag."""

WHEEL_SMOOTHING_S = 0.3
"""Width of the moving average on the reported wheel speeds, s. The board holds its speeds; the
reports carry the encoder's quantisation noise, which as a model input would be a random
reaction torque on the bars (J3 times its rate of change) that the rig never felt."""
WHEEL_SETTLED_RAD_S = 0.5
"""Where the smoothed report is this close to the commanded speed, the wheel is taken to run at
the command: the board's speed loop holds it there, while the reports' mean is off by their
quantisation (about 1e-3 rad/s), and a momentum imbalance that small already grows, over a
few seconds, in the D-bar's unstable roll mode."""


@dataclass(frozen=True)
class Recording:
    """The streams of one run that the fit uses, from its first IMU sample on (t = 0 there).

    Attributes
    ----------
    name : str
        Where it came from (a log folder), for messages.
    imu : ndarray, shape (k, 9)
        Rate (rad/s), specific force (m/s^2), roll, pitch, yaw (rad) at ``t_imu_s``.
    t_imu_s : ndarray, shape (k,), s
    t_wheels_s, wheels_rad_s : ndarray, shapes (kw,) and (kw, n_w)
        Reported wheel speeds, scene wheel order.
    t_servos_s, servos_m : ndarray, shapes (ks,) and (ks, n_servos)
        String lengths of the servos that wind a string, configuration order: the reports
        rendered between them by the commands (:mod:`.servo_render`; the reports alone in a
        log without the commands), or with ``commanded`` the host's commands.
    t_command_s, command_rad_s : ndarray, shapes (kc,) and (kc, n_w)
        Commanded wheel speeds (empty without a ``command`` stream).
    segment_s : float, s
        Length of the multiple-shooting segments (:mod:`.shooting`); 0: one simulation from
        the start.
    segment_start : str
        How a later segment starts: ``"imu"``, the previous one's end turned to the IMU's
        tilt and rate (:func:`.shooting.anchored`); ``"estimate"``, the host estimator's
        logged state where there is one (:func:`.shooting.start_states`).
    anchor_mounting_rpy_rad, anchor_gyro_bias_rad_s : tuple of 3 float, rad and rad/s
        The IMU mounting and gyro bias the ``"imu"`` segment starts read the IMU with.
    t_estimate_s, estimate_x : ndarray, shapes (ke,) and (ke, 6 m)
        The host estimator's reduced coordinates and their rates (m, m/s) where logged
        (empty: none logged).
    """

    name: str
    t_imu_s: np.ndarray
    imu: np.ndarray
    t_wheels_s: np.ndarray
    wheels_rad_s: np.ndarray
    t_servos_s: np.ndarray
    servos_m: np.ndarray
    t_command_s: np.ndarray
    command_rad_s: np.ndarray
    commanded: bool = False
    segment_s: float = 0.0
    segment_start: str = "imu"
    anchor_mounting_rpy_rad: tuple = (0.0, 0.0, 0.0)
    anchor_gyro_bias_rad_s: tuple = (0.0, 0.0, 0.0)
    t_estimate_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    estimate_x: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    servo_response: ServoResponse | None = None


def recording(
    name: str, data: dict, config: RigConfig, n_wheels: int, t0_s=None, commanded=False
) -> Recording:
    """The :class:`Recording` of the streams ``data`` (name -> structured array), from ``t0_s``
    (default: the first IMU sample), when the rig is at the scene's initial state.

    ``commanded``: the string lengths are the host's commands (``command`` stream, every tick)
    rather than the servos' reported positions (``servos`` stream, read less often); the fit's
    ``servo_lag_s`` is then the servos' own first-order response to their commands. Without
    it, where the commands are logged, the reports are rendered between them by the commands
    (:func:`.servo_render.rendered`)."""
    for stream in (streams.IMU, streams.WHEELS, streams.SERVOS):
        if stream not in data or len(data[stream]) < 2:
            raise IdentDataError(f"{name}: stream '{stream}' missing or shorter than two rows")
    imu = data[streams.IMU]
    t0 = float(imu["t_s"][0]) if t0_s is None else float(t0_s)
    keep = imu["t_s"] >= t0 - 1e-9
    cols = [*streams.IMU_RATE, *streams.IMU_ACCEL, *streams.IMU_ANGLE]
    wheels = data[streams.WHEELS]
    strings = [s.string for s in config.servos.servo if s.string]
    goals = data.get(streams.rest_goals(data))
    if commanded:
        if goals is None:
            raise IdentDataError(f"{name}: stream '{streams.COMMAND}' missing")
        servos, servo_cols = goals, [streams.rest_column(s) for s in strings]
    else:
        servos, servo_cols = data[streams.SERVOS], [streams.servo_length_column(s) for s in strings]
    missing = [c for c in servo_cols if c not in servos.dtype.names]
    missing += [c for c in streams.wheel_speed_columns(n_wheels) if c not in wheels.dtype.names]
    if missing:
        raise IdentDataError(f"{name}: columns {missing} missing (a log of another rig?)")
    command = data.get(streams.COMMAND)
    cmd_cols = streams.wheel_command_columns(n_wheels)
    if command is None or len(command) < 1 or any(c not in command.dtype.names for c in cmd_cols):
        t_cmd, cmd = np.zeros(0), np.zeros((0, n_wheels))
    else:
        t_cmd, cmd = command["t_s"] - t0, np.column_stack([command[c] for c in cmd_cols])
    t_servos, lengths = servos["t_s"] - t0, np.column_stack([servos[c] for c in servo_cols])
    response = None
    rest_cols = [streams.rest_column(s) for s in strings]
    if not commanded and goals is not None and len(goals) > 1:
        if all(c in goals.dtype.names for c in rest_cols):
            t_rest = goals["t_s"] - t0
            rest = np.column_stack([goals[c] for c in rest_cols])
            speed = servo_speed_m_s(config)
            t_servos, lengths, response = rendered(t_servos, lengths, t_rest, rest, speed)
    return Recording(
        name,
        imu["t_s"][keep] - t0,
        np.column_stack([imu[c][keep] for c in cols]),
        wheels["t_s"] - t0,
        np.column_stack([wheels[c] for c in streams.wheel_speed_columns(n_wheels)]),
        t_servos,
        lengths,
        t_cmd,
        cmd,
        commanded,
        servo_response=response,
    )


@dataclass(frozen=True)
class FrameMotion:
    """The IMU frame's motion at the IMU time stamps (body axes of the model's IMU frame).

    Attributes
    ----------
    omega_rad_s, force_m_s2 : ndarray, shape (k, 3)
        Angular rate and specific force (gravity felt by the IMU included), body axes.
    R_wb : ndarray, shape (k, 3, 3)
        The frame's axes in the world frame.
    starts : tuple of (ndarray, ndarray)
        At every later segment's start, the state the previous one ended in and the one the
        segment starts from (model state layout), for checks of the segmenting.
    """

    omega_rad_s: np.ndarray
    force_m_s2: np.ndarray
    R_wb: np.ndarray
    starts: tuple = ()


def _check_wheels_played(scene: Scene) -> None:
    """The forward model plays the logged wheel speeds: a scene whose wheels act through the
    motors' reaction needs their torques instead."""
    if torque_driven(scene):
        raise IdentDataError(
            f"scene {scene.name}: [rig_fidelity] motor_reaction needs the wheels' torques, "
            "which identification does not model (it plays the logged wheel speeds): identify "
            "with the scene without the motors' reaction"
        )


def simulate(
    scene: Scene,
    config: RigConfig,
    rec: Recording,
    offsets_m=None,
    servo_lag_s=0.0,
    frame_nodes=IMU_FRAME_NODES,
    imu_latency_s=0.0,
) -> FrameMotion:
    """Drive the rig's model of ``scene`` with the inputs of ``rec``.

    The model is the host's: the rig's scene and servos and the estimator's IMU frame, nothing
    of the simulated rig's truth (its mismatches are what identification must find).

    Parameters
    ----------
    offsets_m : array_like, shape (n_servos,), m, optional
        Added to every reported servo length (zero offsets of the servos' calibration).
    servo_lag_s : float, s
        First-order lag from the servo's position to the string's rest length.
    frame_nodes : tuple of str
        The scene nodes of the IMU's frame (the estimator's ``imu_frame_nodes``).
    imu_latency_s : float, s
        How long before its stamp each IMU sample was taken: the motion is read then (the
        first samples of a segment at most its start).

    Raises
    ------
    IdentDataError
        The scene's wheels act through the motors' reaction, which this model does not drive.
    """
    _check_wheels_played(scene)
    servos = [s for s in config.servos.servo if s.string]
    string_lag_s = 0.0 if rec.commanded else servo_lag_s
    model = TruthConfig(dt_s=STEP_S, imu_frame_nodes=frame_nodes, servo_lag_s=string_lag_s)
    truth = Truth(scene, model, servos)
    offsets = np.zeros(len(servos)) if offsets_m is None else np.asarray(offsets_m, float)
    dt = truth.dt_s
    n = int(np.ceil(rec.t_imu_s[-1] / dt)) + 1
    t_steps = dt * np.arange(n + 1)
    if rec.commanded:
        speed = servo_speed_m_s(config)
        lengths = lagged(rec.t_servos_s, rec.servos_m, t_steps, servo_lag_s, speed) + offsets
    else:
        lengths = _interp(t_steps, rec.t_servos_s, rec.servos_m) + offsets
    speeds = _interp(t_steps, rec.t_wheels_s, rec.wheels_rad_s)
    speeds = _smooth(speeds, int(round(WHEEL_SMOOTHING_S / dt)))
    if len(rec.t_command_s):
        cmd = rec.command_rad_s[command_rows(rec, t_steps)]
        settled = np.abs(speeds - cmd) < WHEEL_SETTLED_RAD_S
        speeds[settled] = cmd[settled]
    starts = shooting.segment_starts(n, dt, rec.segment_s)
    x0s = [None] * len(starts)
    if rec.segment_start == "estimate":
        _check_estimate(rec, truth.model)
        x0s = shooting.start_states(truth.model, t_steps[starts], rec.t_estimate_s, rec.estimate_x)
    # the rig starts at rest in the scene's shape with the wheels already spinning
    truth.wheel_input_rad_s[:] = speeds[0]
    truth.rest_length_m[list(truth.servo_strings.values())] = lengths[0]
    truth.u = truth.model.pack_input(truth.rest_length_m, truth.wheel_input_rad_s)
    ends = [*starts[1:], n]
    parts, jumps = [], []
    anchor = rotation_zyx(*rec.anchor_mounting_rpy_rad), np.asarray(rec.anchor_gyro_bias_rad_s)
    for j, (k0, k1, x0) in enumerate(zip(starts, ends, x0s, strict=True)):
        if j and x0 is None and rec.segment_start == "imu":
            x0 = shooting.anchored(
                truth, truth.stepper.x, rec.t_imu_s, rec.imu, t_steps[k0], *anchor
            )
        if x0 is not None:
            jumps.append((truth.stepper.x.copy(), x0))
            truth.set_state(x0)
        motion = _run(truth, t_steps, lengths, speeds, k0, k1)
        last = k1 == n
        keep = (rec.t_imu_s >= t_steps[k0]) & ((rec.t_imu_s < t_steps[k1]) | last)
        taken = rec.t_imu_s[keep] - imu_latency_s
        parts.append([_interp(taken, t_steps[k0 : k1 + 1], v) for v in motion])
    omega, force, R = (np.concatenate(v) for v in zip(*parts, strict=True))
    return FrameMotion(omega, force, R.reshape(-1, 3, 3), tuple(jumps))


def _run(truth: Truth, t_steps, lengths, speeds, k0: int, k1: int):
    """Step ``truth`` from its present state (at ``t_steps[k0]``) to ``t_steps[k1]`` under the
    inputs of those steps; the IMU frame's rate, specific force and attitude (flattened) at
    every step, shapes (k1 - k0 + 1, 3), (.., 3) and (.., 9)."""
    ids = list(truth.servo_strings)
    model, stepper = truth.model, truth.stepper
    # the state and the input at t_k
    xs, us = np.empty((k1 - k0 + 1, len(stepper.x))), []
    for j, k in enumerate(range(k0, k1 + 1)):
        xs[j] = stepper.x
        us.append(truth.u)
        if k < k1:
            truth.step(dict(zip(ids, lengths[k + 1], strict=True)), speeds[k + 1])
    t = t_steps[k0 : k1 + 1]
    x_dot = np.array([stepper.dynamics(tk, x, u) for tk, x, u in zip(t, xs, us, strict=True)])
    L, k = model.layout, len(t)
    q, q_dot, q_ddot = (
        v.reshape(k, 3, model.m) for v in (xs[:, L.q], xs[:, L.q_dot], x_dot[:, L.q_dot])
    )
    U2 = model.U2.toarray()  # (n, m): a few nodes
    N = np.einsum("ij,kdj->dik", U2, q) + model.N_fixed_T.T[..., None]
    N_dot, N_ddot = (np.einsum("ij,kdj->dik", U2, v) for v in (q_dot, q_ddot))
    omega, force, R = truth.frame_motion(N, N_dot, N_ddot)
    return omega, force, R.reshape(k, 9)


def window(rec: Recording, until_s: float) -> Recording:
    """``rec`` up to ``until_s`` (its IMU samples; the inputs whole), one segment."""
    keep = rec.t_imu_s < until_s
    return replace(rec, t_imu_s=rec.t_imu_s[keep], imu=rec.imu[keep], segment_s=0.0)


def command_rows(rec: Recording, t_s) -> np.ndarray:
    """Index of the command row in force at each of the times ``t_s`` (the latest at or before
    it; the first before the first command)."""
    return np.clip(np.searchsorted(rec.t_command_s, t_s, "right") - 1, 0, None)


def _smooth(values, width):
    """Centred moving average over ``width`` rows (edges: the mean of the rows there)."""
    if width < 2:
        return values
    kernel = np.ones(width) / width
    ones = np.convolve(np.ones(len(values)), kernel, mode="same")
    return np.column_stack([np.convolve(v, kernel, mode="same") / ones for v in values.T])


def _interp(t, tp, values):
    return np.column_stack([np.interp(t, tp, v) for v in values.T])


def sensor_outputs(motion: FrameMotion, mounting_rpy_rad, gyro_bias_rad_s, accel_bias_m_s2):
    """What the IMU reports for ``motion``: rate and specific force (sensor axes, biased),
    shape (k, 6), and the sensor's axes in the world, shape (k, 3, 3)."""
    R_bs = rotation_zyx(*mounting_rpy_rad)
    omega = motion.omega_rad_s @ R_bs + np.asarray(gyro_bias_rad_s)
    force = motion.force_m_s2 @ R_bs + np.asarray(accel_bias_m_s2)
    return np.column_stack([omega, force]), motion.R_wb @ R_bs


def output_error(predicted, rec: Recording) -> np.ndarray:
    """Predicted (:func:`sensor_outputs`) less measured, shape (k, 8): rate, force and the
    attitude's tilt (:func:`tilt_error`)."""
    signals, R_ws = predicted
    return np.column_stack([signals - rec.imu[:, :6], tilt_error(R_ws, rec.imu[:, 6:8])])


def tilt_error(R_ws, roll_pitch_rad) -> np.ndarray:
    """Tilt of the predicted sensor axes ``R_ws`` (k, 3, 3) from the measured ones (roll and
    pitch, (k, 2), rad), shape (k, 2), rad: the rotation between their up directions
    (:func:`gyrohost.geometry.levelling_rotvec`; to first order the horizontal part of
    ``log(R_pred R_meas^T)``), in the world of the measured attitude turned to zero yaw (the
    IMU's yaw is relative and not compared).

    Not the angles' difference: the D-bar takes the sensor's pitch through -90 degrees, where
    roll is singular (it jumps by up to pi between neighbouring samples and the difference says
    nothing of the attitude). The tilt is smooth everywhere; its noise is
    :func:`tilt_std`."""
    roll, pitch = roll_pitch_rad[:, 0], roll_pitch_rad[:, 1]
    R_m = rotation_zyx(roll, pitch, np.zeros_like(roll))  # (3, 3, k)
    # the predicted up direction (sensor axes: R_ws^T z) seen in the measured world
    up = np.einsum("ijk,kj->ki", R_m, R_ws[:, 2, :])
    return levelling_rotvec(up)[:, :2]


def tilt_std(roll_pitch_rad, angle_std_rad: float) -> np.ndarray:
    """Standard deviation of :func:`tilt_error`'s two components, shape (k, 2), rad, for the
    IMU's roll, pitch and yaw each with white noise ``angle_std_rad``.

    The angles' noise turns the attitude about the world axes of the Euler-rate matrix ``E``
    (:func:`gyrohost.estimator.fuse_imu_angle.euler_rate_matrix`), as the estimator fuses them:
    covariance ``std^2 (E E^T + FLOOR^2 I)``. At zero yaw its horizontal block is diagonal,
    ``std^2 diag(cos(pitch)^2 + FLOOR^2, 1 + FLOOR^2)``: at pitch -90 degrees the roll turns
    about the vertical and the tilt about x is left to the floor.
    """
    cp = np.cos(roll_pitch_rad[:, 1])
    return angle_std_rad * np.column_stack(
        [np.sqrt(cp**2 + FLOOR**2), np.full(len(cp), np.sqrt(1.0 + FLOOR**2))]
    )


def noise_std(rec: Recording, rate_std_rad_s, accel_std_m_s2, angle_std_rad) -> np.ndarray:
    """Standard deviation of every column of :func:`output_error` on ``rec``, shape (k, 8)."""
    k = len(rec.t_imu_s)
    return np.column_stack(
        [
            np.full((k, 3), rate_std_rad_s),
            np.full((k, 3), accel_std_m_s2),
            tilt_std(rec.imu[:, 6:8], angle_std_rad),
        ]
    )


def _check_estimate(rec: Recording, model) -> None:
    """The logged estimate's coordinates are the model's (a log of another scene or
    estimator would start the segments from nonsense)."""
    want = 6 * model.layout.m
    if len(rec.t_estimate_s) and rec.estimate_x.shape[1] != want:
        raise IdentDataError(
            f"{rec.name}: estimate.csv holds {rec.estimate_x.shape[1]} q_*/qdot_* columns, the "
            f"scene's model has {want}: segments cannot start from it (--segment-start imu)"
        )
