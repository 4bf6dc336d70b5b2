"""The log schema of a run: every stream the run writes, its columns and its row writers.

Stream columns of the estimator's inputs and outputs come from
:mod:`gyrohost.estimator.streams` (the one place they are named); this module adds the run's own
streams (``events``, ``loop``, ``nodes``, ``truth``, ``replan``) and extra columns after the
estimator's (device clock and status words), which a replay ignores. A scene with an attitude
measure (:func:`gyrohost.control.attitude.attitude_of`, the D-bar) adds a ``tilt_rad`` column to
``nodes`` and ``truth``; a scene with a body frame (``[attitude]``,
:func:`gyrohost.control.attitude.body_frame_of`) adds its attitude (:data:`BODY_ATTITUDE`) to
both. docs/run.md lists them all.
"""

from collections import deque
from dataclasses import dataclass

import numpy as np

from gyrohost.control.attitude import BodyFrame, TiltMeter, node_columns
from gyrohost.drivers import wheelproto as wp
from gyrohost.estimator import fuse_imu_accel, fuse_imu_angle, fuse_imu_rate
from gyrohost.estimator import streams as cols
from gyrohost.estimator.imu_model import tilt as sensor_tilt
from gyrohost.run.health import NisTally, TruthScore
from gyrohost.run.uncertainty import NodeSigma
from gyrotensegrity.attitude import angle_between

RECENT_TILTS = 200
"""Truth tilts kept (1 s of the rig's 5 ms steps), to compare with an estimate that lags."""

IMU_FUSIONS = (fuse_imu_rate, fuse_imu_accel, fuse_imu_angle)
"""The fusions of one IMU sample (each names its ``SOURCE`` and its components' ``LABELS``)."""
INNOVATION_COMPONENTS = {m.SOURCE: m.LABELS for m in IMU_FUSIONS}
"""Innovation components of the IMU's sources (the angles': a rotation vector, world axes)."""


def node_columns_of(names, prefix: str = "") -> list[str]:
    """Columns ``<prefix><node>_<axis>_m`` for scene nodes ``names``."""
    return [f"{prefix}{n}_{a}_m" for n in names for a in "xyz"]


def tilt_column(tilt: TiltMeter | None, prefix: str = "") -> list[str]:
    """The ``<prefix>tilt_rad`` column given an attitude measure, none without."""
    return [] if tilt is None else [f"{prefix}tilt_rad"]


def tilt_of(tilt: TiltMeter | None, N_scene) -> float:
    """Tilt, rad, of scene node positions ``N_scene`` (3, n), m; NaN without a measure."""
    return float("nan") if tilt is None else tilt.tilt(N_scene)


def tilt_value(tilt: TiltMeter | None, value: float) -> tuple:
    """The row cells of :func:`tilt_column`."""
    return () if tilt is None else (value,)


BODY_ATTITUDE = (
    "body_qw",
    "body_qx",
    "body_qy",
    "body_qz",
    "body_roll_rad",
    "body_pitch_rad",
    "body_yaw_rad",
)
"""Columns of a scene's body-frame attitude (:mod:`gyrotensegrity.attitude`): the frame's
rotation from its start as a quaternion (w first, w >= 0) and as roll, pitch, yaw (intrinsic
Z-Y'-X'', about the start frame's axes), rad."""


def body_columns(body: BodyFrame | None) -> list[str]:
    """The :data:`BODY_ATTITUDE` columns given a body frame, none without."""
    return [] if body is None else list(BODY_ATTITUDE)


def body_values(body: BodyFrame | None, N_scene) -> tuple:
    """The row cells of :func:`body_columns` for scene node positions ``N_scene`` (3, n), m."""
    if body is None:
        return ()
    att = body.attitude(N_scene)
    return (*att.quaternion.tolist(), *att.rpy_rad.tolist())


def body_summary(estimate: tuple, truth: tuple | None = None) -> dict:
    """The summary's record of a body attitude: the estimate's quaternion and roll, pitch, yaw
    (cells of :func:`body_values`) and, given the truth's, the truth's and the rotation angle
    between the two, rad (:func:`gyrotensegrity.attitude.angle_between`)."""
    out = {"quaternion": list(estimate[:4]), "rpy_rad": list(estimate[4:])}
    if truth is not None:
        out["truth"] = {"quaternion": list(truth[:4]), "rpy_rad": list(truth[4:])}
        out["error_rad"] = float(angle_between(estimate[:4], truth[:4]))
    return out


@dataclass
class RunStreams:
    """The streams every run writes (opened with :func:`open_run_streams`)."""

    events: object
    loop: object
    imu: object
    wheels: object
    servos: object
    command: object
    servo_goals: object


def open_run_streams(log, strings, servo_strings) -> RunStreams:
    """Open the run's own streams and the device streams.

    Parameters
    ----------
    log : RunLog
    strings : list of str
        Scene strings, scene order (the ``command`` stream).
    servo_strings : list of str
        Strings the servos wind, servo order (the ``servos`` stream).
    """
    names = servo_strings
    return RunStreams(
        events=log.stream(
            "events", ["t_s", "kind", "message"], ("kind", "message"), "phases, faults, outcome"
        ),
        loop=log.stream(
            "loop",
            ["t_s", "late_s", "work_s", "cpu_s", "samples", "estimate_lag_s", "phase"],
            ("phase",),
            "one row per host tick: lateness against the grid, wall and CPU time spent, the "
            "newest estimate's time behind the tick (s)",
        ),
        imu=log.stream(
            cols.IMU, [*cols.imu_columns(), "temperature_degC"], (), "IMU samples at arrival"
        ),
        wheels=log.stream(
            cols.WHEELS,
            [
                *cols.wheels_columns(),
                cols.WHEEL_DEVICE_TIME,
                "seq",
                "status",
                "faults",
                *(f"drive_{i}" for i in range(wp.N_WHEELS)),
            ],
            description="wheel-board telemetry at arrival; drive as a fraction of the supply",
        ),
        servos=log.stream(
            cols.SERVOS,
            [
                *cols.servos_columns(names),
                *(f"{n}_speed_m_s" for n in names),
                *(f"{n}_load" for n in names),
            ],
            description="servo read-back at arrival; load as a fraction of the maximum torque",
        ),
        command=log.stream(
            cols.COMMAND,
            cols.command_columns(strings),
            description="commanded rest lengths (m) and wheel speeds (rad/s), every tick",
        ),
        servo_goals=log.stream(
            cols.SERVO_GOALS,
            cols.goals_columns(strings),
            description="rest lengths (m) as the servos were sent them, when they were",
        ),
    )


class EstimateWriter:
    """Rows of the ``estimate`` and ``nodes`` streams from a :class:`TensegrityEKF`.

    ``estimate`` is the estimator's own row (as ``gyrotens replay`` writes it; its ``tilt_rad``
    is the angle of the sensor z axis from the vertical, unsigned). ``nodes`` holds the scene
    node positions and, given an attitude measure, the signed tilt of the D-bar plane about the
    n2-n4 axis (as in the ``truth`` stream), given a body frame its attitude
    (:data:`BODY_ATTITUDE`), then the standard deviation of the positions and the tilt
    (``std_`` prefix, :class:`~gyrohost.run.uncertainty.NodeSigma`).

    Parameters
    ----------
    log : RunLog
    ekf : TensegrityEKF
    tilt : TiltMeter or None
        The scene's attitude measure (None: no tilt column).
    body : BodyFrame or None
        The scene's body frame (None: no body attitude columns).
    """

    def __init__(self, log, ekf, tilt: TiltMeter | None, body: BodyFrame | None = None):
        self.ekf, self.tilt, self.body = ekf, tilt, body
        self.score = TruthScore(ekf)  # the estimate at the simulated rig's truth samples
        model = ekf.model
        self.names = list(model.scene.node_names)
        self.scene_cols = node_columns(model, self.names)
        self.estimate = log.stream(
            cols.ESTIMATE,
            cols.estimate_columns(ekf.layout.labels()),
            description="EKF state, its standard deviations, IMU-frame angles (rad) and tilt",
        )
        self.nodes = log.stream(
            "nodes",
            [
                "t_s",
                *node_columns_of(self.names),
                *tilt_column(tilt),
                *body_columns(body),
                *node_columns_of(self.names, "std_"),
                *tilt_column(tilt, "std_"),
            ],
            description="scene node positions of the estimate, m; plane tilt, rad; body attitude "
            "(quaternion, roll/pitch/yaw rad); the standard deviation of positions and tilt (std_)",
        )
        self.sigma = NodeSigma(ekf, self.scene_cols, tilt)

    def write(self, t_s: float) -> tuple[float, tuple | None]:
        """Write one row of each stream at host time ``t_s``; returns the plane tilt, rad (NaN
        without an attitude measure), and the body attitude's cells (:data:`BODY_ATTITUDE`;
        None without a body frame)."""
        ekf = self.ekf
        x = ekf.x
        N_all, _ = ekf.batch_nodes(x[None, :])
        N = N_all[0][:, self.scene_cols]
        R, euler = ekf.attitude()
        tilt = tilt_of(self.tilt, N)
        std = np.sqrt(np.clip(np.diag(ekf.P), 0.0, None))
        self.estimate.write(t_s, int(ekf.status), *x, *std, *euler, sensor_tilt(R))
        self.score.estimate()
        node_std, tilt_std = self.sigma.std(N, ekf.P)
        body = body_values(self.body, N)
        self.nodes.write(
            t_s, *N.T.ravel(), *tilt_value(self.tilt, tilt), *body, *node_std, *tilt_std
        )
        return tilt, (body or None)


class InnovationWriter:
    """The EKF's ``log`` callback: one ``innov_<source>`` row per fusion attempt.

    Streams open on a source's first innovation (then its dimension is known). Time is the
    filter's time of the fusion, the host time of the fused sample.
    """

    def __init__(self, log, servo_strings):
        self.log = log
        self.components = dict(INNOVATION_COMPONENTS, servos=tuple(servo_strings))
        self.streams: dict = {}
        self.tally = NisTally()  # the estimator's health in the summary

    def __call__(self, inn) -> None:
        self.tally.add(inn)
        stream = self.streams.get(inn.source)
        if stream is None:
            k = len(inn.innovation)
            comps = self.components.get(inn.source) or tuple(f"w{i}" for i in range(k))
            stream = self.log.stream(
                cols.innovation_stream(inn.source),
                cols.innovation_columns(comps[:k]),
                description=f"{inn.source} innovations (measurement units), variances, NIS, gate",
            )
            self.streams[inn.source] = stream
        stream.write(
            inn.t_s,
            *inn.innovation,
            *inn.variance,
            inn.nis,
            inn.test_ratio,
            int(inn.accepted),
            inn.rejected_count,
        )


class TruthProbe:
    """Writes the simulated rig's truth samples into the ``truth`` stream as they arrive.

    A sample's ``t_s`` is the rig time its state belongs to (its step's, plus the slip) on the
    host clock (rig time zero is known in ``time.monotonic_ns``), so the truth lines up with
    the device samples the rig made of that state, between its 5 ms steps and when the rig
    slips behind the wall clock under load; ``rig_t_s`` is the rig's time when it was sampled,
    ``wall_t_s`` the host's.

    Parameters
    ----------
    rig : RigProcess
        Source of :class:`~gyrohost.simrig.process.TruthSample` (``truth()``), node and string
        names, wheel count.
    log : RunLog
    tilt : TiltMeter or None
        The scene's attitude measure (None: no tilt column).
    t0_ns : int
        ``time.monotonic_ns`` of the run's time zero, ns.
    body : BodyFrame or None
        The scene's body frame (None: no body attitude columns).
    """

    def __init__(self, rig, log, tilt: TiltMeter | None, t0_ns: int, body: BodyFrame | None = None):
        self.rig, self.tilt, self.t0_ns, self.body = rig, tilt, t0_ns, body
        self.latest_tilt = float("nan")
        self.recent_tilts: deque = deque(maxlen=RECENT_TILTS)  # (t_s, tilt_rad)
        self.recent_nodes: deque = deque(maxlen=RECENT_TILTS)  # (t_s, N), with a body frame
        self.stream = log.stream(
            "truth",
            [
                "t_s",
                "rig_t_s",
                "truth_t_s",
                "wall_t_s",
                *node_columns_of(rig.node_names),
                *tilt_column(tilt),
                *body_columns(body),
                *(f"omega_{i}_rad_s" for i in range(rig.n_wheels)),
                *(cols.rest_column(s) for s in rig.string_names),
            ],
            description="the simulated rig's truth at its rig time on the host clock (t_s)",
        )

    def write(self, score=None) -> None:
        """Write every truth sample received since the last call; score the estimate at each
        (``score``: a :class:`TruthScore`, or the estimator's process, which keeps one; None
        while no estimator is fed)."""
        for s in self.rig.truth():
            self.latest_tilt = tilt_of(self.tilt, s.N)
            t_s = (self.rig.t0_ns - self.t0_ns) * 1e-9 + s.state_rig_t_s
            self.recent_tilts.append((t_s, self.latest_tilt))
            if self.body is not None:
                self.recent_nodes.append((t_s, s.N))
            if score is not None:
                score.truth(t_s, s.N, s.omega_w_rad_s, s.rest_length_m)
            self.stream.write(
                t_s,
                s.rig_t_s,
                s.truth_t_s,
                (s.t_ns - self.t0_ns) * 1e-9,
                *s.N.T.ravel(),
                *tilt_value(self.tilt, self.latest_tilt),
                *body_values(self.body, s.N),
                *s.omega_w_rad_s,
                *s.rest_length_m,
            )

    def tilt_at(self, t_s: float) -> float:
        """The truth's plane tilt, rad, at host time ``t_s`` (interpolated between the recent
        samples, the nearest outside them; NaN before any)."""
        if not self.recent_tilts:
            return float("nan")
        t, tilt = np.array(self.recent_tilts).T
        return float(np.interp(t_s, t, tilt))

    def body_at(self, t_s: float) -> tuple | None:
        """The truth's body attitude (cells of :func:`body_values`) at host time ``t_s``, of the
        node positions interpolated between the recent samples (the nearest outside them);
        None without a body frame or before any sample."""
        if not self.recent_nodes:
            return None
        t = np.array([sample[0] for sample in self.recent_nodes])
        N = np.stack([sample[1] for sample in self.recent_nodes])
        cells = N.reshape(len(t), -1).T
        N_t = np.array([np.interp(t_s, t, cell) for cell in cells]).reshape(N.shape[1:])
        return body_values(self.body, N_t)


class ReplanWriter:
    """Rows of the ``replan`` stream: every plan of a :class:`gyrohost.control.Maneuver`, the
    first included, written once (``write`` takes the maneuver's whole record list).

    Parameters
    ----------
    log : RunLog
    t_schedule_s : callable() -> float
        Host time at schedule time zero, s (known once the schedule phase starts).
    """

    def __init__(self, log, t_schedule_s):
        self.t_schedule_s = t_schedule_s
        self.done = 0
        self.stream = log.stream(
            "replan",
            [
                "t_s",
                "schedule_t_s",
                "tilt_rad",
                "predicted_tilt_rad",
                "plan_time_s",
                "accepted",
                "kappa",
                "error_rad",
                "predicted_error_rad",
                "message",
            ],
            ("message",),
            "plans of the maneuver: start (host and schedule time, s), estimated tilt there, "
            "the plan's landing tilt (rad; NaN for an attitude), optimiser wall time (s), "
            "accepted, wheel gain, the estimate's and the plan's landing distance from the "
            "target (rad; geodesic for an attitude)",
        )

    def write(self, records) -> None:
        """Write the records not written yet."""
        for r in records[self.done :]:
            message = " ".join(str(r.message).replace(",", ";").split())
            self.stream.write(
                self.t_schedule_s() + r.t_s,
                r.t_s,
                r.tilt_rad,
                r.predicted_tilt_rad,
                r.plan_time_s,
                int(r.accepted),
                r.kappa,
                r.error_rad,
                r.predicted_error_rad,
                message,
            )
        self.done = len(records)
