"""What the run loop writes: the log streams, their rows, the truth probe and loop timing.

Stream columns of the estimator's inputs and outputs come from
:mod:`gyrohost.estimator.streams` (the one place they are named); this module adds the run
loop's own streams (``nodes``, ``truth``, ``loop``, ``events``) and extra columns after the
estimator's (device clock and status words), which a replay ignores. docs/run.md lists them all.
"""

from dataclasses import dataclass, field

import numpy as np

from gyrohost.control.attitude import Attitude, node_columns, plane_frame, tilt_angle
from gyrohost.estimator import streams as cols
from gyrohost.estimator.imu_model import tilt as sensor_tilt

PLANE_NODES = ("n1", "n2", "n3", "n4")
INNOVATION_COMPONENTS = {
    "imu_rate": ("x", "y", "z"),
    "imu_accel": ("x", "y", "z"),
    "imu_angle": ("roll", "pitch", "yaw"),
}


def node_columns_of(names, prefix: str = "") -> list[str]:
    """Columns ``<prefix><node>_<axis>_m`` for scene nodes ``names``."""
    return [f"{prefix}{n}_{a}_m" for n in names for a in "xyz"]


class TiltMeter:
    """Tilt of the D-bar plane from scene node positions (as the planner measures it).

    Parameters
    ----------
    model : gyrotensegrity.Model
        Fixes the tilt axis (the n2-n4 axis at rest) and the reference normal.
    """

    def __init__(self, model):
        self.attitude = Attitude(model)
        names = list(model.scene.node_names)
        self.cols = [names.index(n) for n in PLANE_NODES]

    def tilt(self, N_scene) -> float:
        """Tilt, rad, of scene node positions ``N_scene`` (3, n_scene), m."""
        normal = plane_frame(N_scene, self.cols)[:, 2]
        return tilt_angle(normal, self.attitude.axis, self.attitude.normal0)


class EstimateWriter:
    """Rows of the ``estimate`` and ``nodes`` streams from a :class:`TensegrityEKF`.

    ``estimate`` is the estimator's own row (as ``gyrotens replay`` writes it; its ``tilt_rad``
    is the angle of the sensor z axis from the vertical, unsigned). ``nodes`` holds the scene
    node positions and the signed tilt of the D-bar plane about the n2-n4 axis
    (:class:`TiltMeter`, as in the ``truth`` stream).

    Parameters
    ----------
    log : RunLog
    ekf : TensegrityEKF
    tilt : TiltMeter
    """

    def __init__(self, log, ekf, tilt: TiltMeter):
        self.ekf, self.tilt = ekf, tilt
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
            ["t_s", *node_columns_of(self.names), "tilt_rad"],
            description="scene node positions of the estimate, m; plane tilt, rad",
        )

    def write(self, t_s: float) -> tuple[np.ndarray, float]:
        """Write one row of each stream at host time ``t_s``; returns (N (3, n), plane tilt rad)."""
        ekf = self.ekf
        x = ekf.x
        N_all, _ = ekf.batch_nodes(x[None, :])
        N = N_all[0][:, self.scene_cols]
        R, euler = ekf.attitude()
        tilt = self.tilt.tilt(N)
        std = np.sqrt(np.clip(np.diag(ekf.P), 0.0, None))
        self.estimate.write(t_s, int(ekf.status), *x, *std, *euler, sensor_tilt(R))
        self.nodes.write(t_s, *N.T.ravel(), tilt)
        return N, tilt


class InnovationWriter:
    """The EKF's ``log`` callback: one ``innov_<source>`` row per fusion attempt.

    Streams open on a source's first innovation (then its dimension is known). Time is the
    filter's time of the fusion, the host time of the fused sample.
    """

    def __init__(self, log, servo_strings):
        self.log = log
        self.components = dict(INNOVATION_COMPONENTS, servos=tuple(servo_strings))
        self.streams: dict = {}

    def __call__(self, inn) -> None:
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

    A sample's ``t_s`` is its rig time on the host clock (rig time zero is known in
    ``time.monotonic_ns``), so the truth lines up with the device samples the rig made at that
    rig time even when the rig slips behind the wall clock under load; ``wall_t_s`` is when it
    was sampled.

    Parameters
    ----------
    rig : RigProcess
        Source of :class:`~gyrohost.rig.process.TruthSample` (``truth()``), node and string
        names, wheel count.
    log : RunLog
    tilt : TiltMeter
    t0_ns : int
        ``time.monotonic_ns`` of the run's time zero, ns.
    """

    def __init__(self, rig, log, tilt: TiltMeter, t0_ns: int):
        self.rig, self.tilt, self.t0_ns = rig, tilt, t0_ns
        self.latest_tilt = float("nan")
        self.stream = log.stream(
            "truth",
            [
                "t_s",
                "rig_t_s",
                "truth_t_s",
                "wall_t_s",
                *node_columns_of(rig.node_names),
                "tilt_rad",
                *(f"omega_{i}_rad_s" for i in range(rig.n_wheels)),
                *(cols.rest_column(s) for s in rig.string_names),
            ],
            description="the simulated rig's truth at its rig time on the host clock (t_s)",
        )

    def write(self) -> None:
        """Write every truth sample received since the last call."""
        for s in self.rig.truth():
            self.latest_tilt = self.tilt.tilt(s.N)
            self.stream.write(
                (self.rig.t0_ns - self.t0_ns) * 1e-9 + s.rig_t_s,
                s.rig_t_s,
                s.truth_t_s,
                (s.t_ns - self.t0_ns) * 1e-9,
                *s.N.T.ravel(),
                self.latest_tilt,
                *s.omega_w_rad_s,
                *s.rest_length_m,
            )


@dataclass
class LoopTimer:
    """Periods and lateness of the fixed-rate loop's ticks.

    Parameters
    ----------
    period_s : float, s
        The nominal period.
    """

    period_s: float
    starts: list = field(default_factory=list)
    lates: list = field(default_factory=list)

    def record(self, start_s: float, due_s: float) -> None:
        """A tick started at ``start_s`` (host time, s) that was due at ``due_s``."""
        self.starts.append(start_s)
        self.lates.append(start_s - due_s)

    def stats(self) -> dict:
        """Period mean, std, p99 and max, lateness max and ticks more than a period late (s)."""
        periods = np.diff(self.starts)
        if periods.size == 0:
            return {"ticks": len(self.starts), "nominal_period_s": self.period_s}
        lates = np.array(self.lates)
        return {
            "ticks": len(self.starts),
            "nominal_period_s": self.period_s,
            "period_mean_s": float(periods.mean()),
            "period_std_s": float(periods.std()),
            "period_p99_s": float(np.percentile(periods, 99)),
            "period_max_s": float(periods.max()),
            "late_max_s": float(lates.max()),
            "late_p99_s": float(np.percentile(lates, 99)),
            "overruns": int(np.sum(lates > self.period_s)),
        }


def jitter_line(stats: dict) -> str:
    """One line of the loop timing figures (ms)."""
    if "period_mean_s" not in stats:
        return f"loop: {stats['ticks']} ticks (too few for timing figures)"

    def ms(key):
        return 1e3 * stats[key]

    rate = 1.0 / stats["nominal_period_s"]
    return (
        f"loop at {rate:g} Hz: {stats['ticks']} ticks, period mean {ms('period_mean_s'):.3f} ms, "
        f"std {ms('period_std_s'):.3f} ms, p99 {ms('period_p99_s'):.3f} ms, "
        f"max {ms('period_max_s'):.3f} ms; late max {ms('late_max_s'):.3f} ms, "
        f"{stats['overruns']} overruns"
    )


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
                "message",
            ],
            ("message",),
            "plans of the maneuver: start (host and schedule time, s), estimated tilt there, "
            "the plan's landing tilt (rad), optimiser wall time (s), accepted, wheel gain",
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
                message,
            )
        self.done = len(records)
