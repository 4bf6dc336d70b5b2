"""Feeding recorded streams to the filter in time order (shared by replay and the tests).

The IMU's sample times are reconstructed from its arrival stamps by :class:`RegularClock`
(online, ``gyrohost.run.dispatch``) or :func:`regular_times` (a logged stream, before it is
handed here); the wheel board's from its own clock by :class:`DeviceClock` (:func:`wheel_times`
for a logged stream). Samples of all streams are merged by time; at equal
times commands come first (the servos' goals, then the wheels'), then the IMU, the wheels and
the servos (a fixed order, so a replay is deterministic). The rest lengths' input comes from the
``servo_goals`` stream, stamped when the goals went onto the bus, where the log has it
(:func:`.streams.rest_goals`), the wheels' from ``command``. Before each sample the filter
predicts to its time; a gap longer than ``process_dt_s`` is bridged in prediction steps, each
reported like a sample (this is where time-outs are raised).
"""

import math
from collections import deque

import numpy as np

from . import streams as cols

_ORDER = (cols.SERVO_GOALS, cols.COMMAND, cols.IMU, cols.WHEELS, cols.SERVOS)


def _servo_map(model, names):
    strings = [s.name for s in model.scene.strings]
    found = [(c, strings.index(s)) for s in strings if (c := cols.servo_length_column(s)) in names]
    return [c for c, _ in found], np.array([i for _, i in found], dtype=int)


class RegularClock:
    """Sample times of a device that samples every ``period_s``, from its arrival stamps, one
    sample at a time (online; :func:`regular_times` for a whole stream).

    Reads in bursts stamp several samples alike; a sample cannot have been taken later than its
    arrival, nor earlier than ``max_delay_s`` before it, nor sooner than ``period_s`` after the
    previous one (as reconstructed). ``period_s`` 0 keeps the arrival stamps.

    A sample lost on the way (a corrupt frame, a row skipped in a replay) would leave every
    later time a period early, since the next arrival takes the lost one's slot. So the clock
    watches the delays it implies: once the smallest delay of the last :attr:`WINDOW` samples
    exceeds the smallest of the whole stream by half a period or more, the lost periods are
    counted and the grid moves on by them (a burst of late samples cannot do that: the
    window holds on-time ones too).

    Parameters
    ----------
    period_s, max_delay_s : float, s
    """

    WINDOW = 50
    """Samples over which the smallest delay is watched (0.5 s at 100 Hz)."""

    def __init__(self, period_s: float, max_delay_s: float):
        self.period_s, self.max_delay_s = period_s, max_delay_s
        self.last_s: float | None = None
        self.floor_s = math.inf  # the smallest delay seen, s
        self._recent: deque = deque(maxlen=self.WINDOW)

    def __call__(self, arrival_s: float) -> float:
        """The sample time, s, of the sample that arrived at ``arrival_s``, s."""
        a = float(arrival_s)
        t = a
        if self.last_s is not None and self.period_s > 0.0:
            t = max(a - self.max_delay_s, min(a, self.last_s + self.period_s))
            t = min(t + self._lost_periods(a - t) * self.period_s, a)
        self.last_s = t
        return t

    def _lost_periods(self, delay_s: float) -> int:
        self.floor_s = min(self.floor_s, delay_s)
        self._recent.append(delay_s)
        if len(self._recent) < self.WINDOW:
            return 0
        excess = min(self._recent) - self.floor_s
        lost = int(round(excess / self.period_s)) if excess >= 0.5 * self.period_s else 0
        if lost:
            self._recent = deque((d - lost * self.period_s for d in self._recent), self.WINDOW)
        return lost


def regular_times(arrival_s, period_s, max_delay_s):
    """:class:`RegularClock` over a whole stream (causal: each time depends on earlier arrivals
    only).

    Parameters
    ----------
    arrival_s : ndarray, shape (k,), s
    period_s, max_delay_s : float, s

    Returns
    -------
    ndarray, shape (k,), s
    """
    clock = RegularClock(period_s, max_delay_s)
    return np.array([clock(a) for a in np.asarray(arrival_s, dtype=float)])


class DeviceClock:
    """Sample times on the host's clock of a device that stamps its samples with its own (the
    wheel board's ``t_us``: microseconds, 32 bits), one sample at a time (online;
    :func:`device_times` for a whole stream).

    The time is the device's plus an offset, the smallest ``arrival - device`` of the last
    :attr:`WINDOW` samples less ``wire_s``: a sample never arrives before it was taken and its
    frame has crossed the wire, and the fastest of many shows the link's shortest delay (the
    window follows the two crystals' drift, 1e-4 at most: 0.2 ms over it). Arrival stamps
    alone carry the link's and the reader's jitter, 0-11 ms on the simulated rig, which in a
    speed ramp reads as 1 rad/s. A device clock that wraps is unwrapped; one that steps back
    (the board reset) starts the window again.

    Parameters
    ----------
    wire_s : float
        A frame's time on the wire, s (``wheel_wire_s``).
    """

    WINDOW = 100
    """Samples over which the smallest delay is taken (2 s of 50 Hz telemetry)."""
    WRAP_US = 1 << 32

    def __init__(self, wire_s: float = 0.0):
        self.wire_s = wire_s
        self._recent: deque = deque(maxlen=self.WINDOW)
        self._last_us: int | None = None
        self._wraps = 0

    def __call__(self, arrival_s: float, device_us) -> float:
        """The host time, s, of the sample stamped ``device_us`` that arrived at ``arrival_s``."""
        d = int(device_us)
        if self._last_us is not None and d < self._last_us:
            if self._last_us - d > self.WRAP_US // 2:
                self._wraps += 1
            else:  # the device restarted its clock
                self._recent.clear()
                self._wraps = 0
        self._last_us = d
        device_s = (d + self._wraps * self.WRAP_US) * 1e-6
        sent_s = float(arrival_s) - self.wire_s
        self._recent.append(sent_s - device_s)
        return min(device_s + min(self._recent), sent_s)  # round-off: not after it


def device_times(arrival_s, device_us, wire_s=0.0):
    """:class:`DeviceClock` over a whole stream (causal), shape (k,) s."""
    clock = DeviceClock(wire_s)
    return np.array([clock(a, d) for a, d in zip(arrival_s, device_us, strict=True)])


def wheel_times(wheels, config):
    """Times (k,) s at which the run loop fuses the samples of a logged ``wheels`` stream: on
    the board's clock (``wheel_times = "device"``, where the log has it), else as stamped on
    arrival."""
    if config.wheel_times == "arrival" or cols.WHEEL_DEVICE_TIME not in wheels.dtype.names:
        return np.array(wheels["t_s"], float)
    return device_times(wheels["t_s"], wheels[cols.WHEEL_DEVICE_TIME], config.wheel_wire_s)


def events(data, imu_latency_s: float = 0.0):
    """(t_s, stream, row index) of every sample of the streams in ``data``, merged in order of
    the time each was taken: an IMU sample ``imu_latency_s`` before its stamp ``t_s`` (the
    others at their stamps).

    A recording is fused in the order its samples were taken, not stamped: the filter then
    predicts to each sample's own time and needs no step back along the dynamics, so the
    likelihood of a replay changes smoothly with the latency (the filter fit fits it)."""
    out = []
    for rank, name in enumerate(_ORDER):
        if name in data:
            t = data[name]["t_s"]
            lead = imu_latency_s if name == cols.IMU else 0.0
            out += [(float(t[i]) - lead, rank, i) for i in range(len(t))]
    out.sort()
    return [(t, _ORDER[rank], i) for t, rank, i in out]


def run(ekf, data, on_step=None):
    """Run ``ekf`` over the streams ``data`` (dict of structured arrays, columns of .streams).

    Parameters
    ----------
    on_step : callable(ekf, stream), optional
        Called after every sample (``stream`` its stream name) and every bridging prediction
        step (``stream`` = ``"predict"``).
    """
    model = ekf.model
    strings = [s.name for s in model.scene.strings]
    rest_cols = [cols.rest_column(s) for s in strings]
    servo_cols, servo_idx = (
        _servo_map(model, data[cols.SERVOS].dtype.names) if cols.SERVOS in data else ([], None)
    )
    n_w = len(model.wheel_bars)
    wheel_cols = cols.wheel_speed_columns(n_w)
    command = data.get(cols.COMMAND)
    cmd_cols = cols.wheel_command_columns(n_w)
    if command is None or any(c not in command.dtype.names for c in cmd_cols):
        cmd_cols = None  # a log without wheel commands: the wheels held
    goals_from = cols.rest_goals(data)
    dt = ekf.config.process_dt_s
    for taken, name, i in events(data, ekf.config.imu_latency_s):
        while taken - ekf.t > dt * (1.0 + 1e-9):
            ekf.advance(ekf.t + dt)
            if on_step:
                on_step(ekf, "predict")
        row = data[name][i]
        t = float(row["t_s"])  # the stamp: the IMU's is taken back by its latency again
        if name in (cols.COMMAND, cols.SERVO_GOALS):
            rest = [row[c] for c in rest_cols] if name == goals_from else None
            wheels = (
                None if cmd_cols is None or name != cols.COMMAND else [row[c] for c in cmd_cols]
            )
            ekf.set_input(rest, t, wheels)
            continue
        if name == cols.IMU:
            ekf.fuse_imu(
                t,
                [row[c] for c in cols.IMU_RATE],
                [row[c] for c in cols.IMU_ACCEL],
                [row[c] for c in cols.IMU_ANGLE],
            )
        elif name == cols.WHEELS:
            ekf.fuse_wheels(t, [row[c] for c in wheel_cols])
        elif servo_cols:
            ekf.fuse_servos(t, [row[c] for c in servo_cols], servo_idx)
        if on_step:
            on_step(ekf, name)
