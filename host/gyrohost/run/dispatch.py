"""Per-device handling of the samples the readers queue: log each one, fuse the newest.

One small handler per device (:class:`ImuHandler`, :class:`WheelHandler`, :class:`ServoHandler`,
and :class:`GoalHandler` for the goals the servo worker sent) writes its device's stream row and
hands the sample to the estimator; :class:`Dispatcher` drains the queue once a tick, in time
order, and decides which samples are fused.
"""

import queue

import numpy as np

from gyrohost.estimator.sample_feed import DeviceClock, RegularClock
from gyrohost.run.devices import Sample


class ImuHandler:
    """IMU samples (:class:`~gyrohost.drivers.imu.ImuSample`): the ``imu`` stream, fused.

    Logged at their arrival stamps; fused at the times of the IMU's own output grid
    (:class:`~gyrohost.estimator.sample_feed.RegularClock` over every sample, as ``gyrotens replay``
    reconstructs them from the log): an arrival stamp carries the serial link's and the reader
    thread's delay, which the filter would take for motion.

    Parameters
    ----------
    stream : Stream
    config : EstimatorConfig
        ``imu_period_s`` (0: fuse at the arrival stamps) and ``imu_max_delay_s``.
    """

    device = "imu"
    every_sample = False  # a measurement: the newest of a tick will do

    def __init__(self, stream, config):
        self.stream = stream
        self.clock = RegularClock(config.imu_period_s, config.imu_max_delay_s)

    def take(self, t_s: float, v, ekf) -> None:
        """Log the sample that arrived at host time ``t_s``; fuse it unless ``ekf`` is None."""
        self.stream.write(t_s, *v.omega_rad_s, *v.accel_m_s2, *v.euler_rad, v.temperature_degC)
        t_sample_s = self.clock(t_s)
        if ekf is not None:
            ekf.fuse_imu(t_sample_s, v.omega_rad_s, v.accel_m_s2, v.euler_rad)


class WheelHandler:
    """Wheel-board telemetry: the ``wheels`` stream; the scene's wheels fused.

    Logged at their arrival stamps (and the board's ``t_us``); fused at the board's own time
    put on the host's clock (:class:`~gyrohost.estimator.sample_feed.DeviceClock`, as ``gyrotens
    replay`` does from the log), unless ``wheel_times`` is ``"arrival"``.

    Parameters
    ----------
    stream : Stream
    n_wheels : int
        Wheels of the scene (the board's first ``n_wheels``).
    config : EstimatorConfig
    """

    device = "wheels"
    every_sample = False  # a measurement: the newest of a tick will do
    SEQ_MOD = 1 << 16
    """The telemetry's sequence number counts modulo this (docs/protocol.md)."""

    def __init__(self, stream, n_wheels: int, config):
        self.stream, self.n_wheels = stream, n_wheels
        self.clock = DeviceClock(config.wheel_wire_s) if config.wheel_times == "device" else None
        self.sequence_gaps = 0  # places where telemetry frames went missing
        self.frames_lost = 0
        self._last_seq: int | None = None

    def take(self, t_s: float, v, ekf) -> None:
        """Log the sample that arrived at host time ``t_s``; fuse it unless ``ekf`` is None."""
        self._count_gap(v.seq)
        self.stream.write(t_s, *v.omega_rad_s, v.t_us, v.seq, v.status, v.faults, *v.drive)
        t_sample_s = t_s if self.clock is None else self.clock(t_s, v.t_us)
        if ekf is not None:
            ekf.fuse_wheels(t_sample_s, np.array(v.omega_rad_s)[: self.n_wheels])

    def _count_gap(self, seq: int) -> None:
        """Count the frames missing before the one numbered ``seq`` (a corrupt frame dropped,
        a byte stream read by another program)."""
        if self._last_seq is not None:
            missing = (seq - self._last_seq - 1) % self.SEQ_MOD
            if missing:
                self.sequence_gaps += 1
                self.frames_lost += missing
        self._last_seq = seq


class ServoHandler:
    """Servo read-back (a list of ServoState, servo order): the ``servos`` stream, fused.

    Parameters
    ----------
    stream : Stream
    strings : list of str
        Scene strings, scene order.
    servo_strings : list of str
        The string each servo winds, servo order.

    Attributes
    ----------
    latest : list of ServoState
        The newest read-back (empty before the first).
    """

    device = "servos"
    every_sample = False  # a measurement: the newest of a tick will do

    def __init__(self, stream, strings, servo_strings):
        self.stream, self.strings, self.servo_strings = stream, strings, servo_strings
        self.latest: list = []

    def take(self, t_s: float, v, ekf) -> None:
        """Log the sample taken at host time ``t_s``; fuse it unless ``ekf`` is None."""
        self.stream.write(
            t_s,
            *(s.length_m for s in v),
            *(s.speed_m_s for s in v),
            *(s.load_fraction for s in v),
        )
        self.latest = v
        if ekf is not None:
            idx = [self.strings.index(name) for name in self.servo_strings]
            ekf.fuse_servos(t_s, [s.length_m for s in v], idx)


class GoalHandler:
    """The goals the servo worker sent (servo name -> string length, m): the ``servo_goals``
    stream, and the estimator's rest-length input from the time they went onto the bus.

    Parameters
    ----------
    stream : Stream
    strings : list of str
        Scene strings, scene order.
    servo_strings : dict
        Servo name -> the scene string it winds.
    rest_m : sequence of float
        Every string's rest length before the first goal, scene order: strings no goal names
        keep theirs.
    """

    device = "servo_goals"
    every_sample = True  # an input: each goal holds until the next, none may be left out

    def __init__(self, stream, strings, servo_strings: dict, rest_m):
        self.stream = stream
        self.index = {name: strings.index(s) for name, s in servo_strings.items()}
        self.rest = np.array(rest_m, dtype=float)

    def take(self, t_s: float, v, ekf) -> None:
        """Log the goals sent at host time ``t_s``; give them to ``ekf`` unless None."""
        for name, length in v.items():
            self.rest[self.index[name]] = length
        self.stream.write(t_s, *self.rest)
        if ekf is not None:
            ekf.set_input(self.rest.copy(), t_s)


class Dispatcher:
    """Drains the readers' queue once a tick and hands each sample to its device's handler.

    Parameters
    ----------
    samples : queue.Queue
        Where the readers put :class:`~gyrohost.run.devices.Sample` and faults.
    handlers : list
        One handler per device (``device`` names it, as in ``Sample.device``; with
        ``every_sample`` True each of its samples is given to the estimator, else the newest).
    max_fused_per_tick : int
        Samples of one device fused per tick at most (the newest); older ones are only logged,
        so a loop that fell behind catches up instead of spiralling.

    Attributes
    ----------
    skipped : dict
        Device -> samples logged but not fused.
    """

    def __init__(self, samples: queue.Queue, handlers, max_fused_per_tick: int):
        self.queue = samples
        self.handlers = {h.device: h for h in handlers}
        self.max_fused = max_fused_per_tick
        self.skipped: dict[str, int] = {}

    def drain(self, t0_ns: int, ekf) -> tuple[int, list]:
        """Log every queued sample in time order, fuse the fusable ones into ``ekf`` (None:
        none); returns (samples taken, faults queued by the readers)."""
        items = []
        while True:
            try:
                items.append(self.queue.get_nowait())
            except queue.Empty:
                break
        faults = [i for i in items if isinstance(i, BaseException)]
        samples = sorted((i for i in items if isinstance(i, Sample)), key=lambda s: s.t_ns)
        for sample in samples:
            t_s = (sample.t_ns - t0_ns) * 1e-9
            handler = self.handlers[sample.device]
            fuse = ekf is not None and t_s >= ekf.t_start
            fuse = fuse and (handler.every_sample or self._newest(sample, samples))
            handler.take(t_s, sample.value, ekf if fuse else None)
        return len(samples), faults

    def _newest(self, sample: Sample, samples: list) -> bool:
        newer = sum(1 for s in samples if s.device == sample.device and s.t_ns > sample.t_ns)
        if newer < self.max_fused:
            return True
        self.skipped[sample.device] = self.skipped.get(sample.device, 0) + 1
        return False
