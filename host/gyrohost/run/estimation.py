"""The run's estimator in a child process, so its fusion never delays the loop's commands.

The EKF costs a few ms of CPU per fused sample; in the loop's thread it made the 100 Hz ticks late
by 5 to 55 ms, and a late tick sends the servos a larger, irregular step that the filter's servo
model does not know (reports/estimator-history.md#the-estimator-out-of-the-loop). Here the loop
hands each tick's stamped samples, commands and truth samples to
:class:`EstimatorProcess`, which sends them down a pipe in one message; the child
(:func:`_serve`) calls the filter with them in the same order as the loop did, so the result is
the same filter run, only later. The child's rows (``estimate``, ``nodes``, ``innov_<source>``)
come back and are written by the loop into the run's log, with the newest estimate (time,
status word, tilt, body attitude, state) for the limits, the readout and a maneuver.

A fault in the child (the filter's :class:`~gyrohost.estimator.errors.EstimatorError`) comes back
and is raised in the loop; the child then only waits to be stopped. The child ignores the
interrupting signals (the parent stops it after the safe state; it starts with them blocked, so
a Ctrl-C during its start-up does not reach it either) and exits quietly when its parent is gone
or has closed the pipe.
"""

import math
import multiprocessing
import os
import time
from collections import deque

import numpy as np

from gyrohost.estimator import fuse_servos, fuse_wheels
from gyrohost.estimator.ekf import Status
from gyrohost.estimator.fusion_horizon import FUSIONS, FusionHorizon
from gyrohost.gcfreeze import heap_frozen
from gyrohost.run.errors import RunError
from gyrohost.run.streams import IMU_FUSIONS
from gyrohost.sigint import (
    InterruptsBlocked,
    InterruptsHeld,
    ignore_interrupts,
    unblock_interrupts,
)

from .errors import EstimatorProcessError

READY_TIMEOUT_S = 60.0
"""Longest wait for the child to import and build the scene's model, s."""
STOP_TIMEOUT_S = 30.0
"""Longest wait at the end of a run for the child to finish the samples it was sent, s."""

NICE = 15
"""The child's niceness: the loop's commands and the devices come first, the estimate may lag
(a third of the CPU time of a process at niceness 0 when they compete for a core)."""

_PIPE_ERRORS = (EOFError, OSError)


class EstimatorProcess:
    """The EKF of a run in a child process, fed and read as the loop fed and read the filter.

    Parameters
    ----------
    model : Model
        The run's model (the child builds its own from ``scene_path``).
    scene_path : path
        The scene file of ``model``.
    config : EstimatorConfig
    servo_strings : list of str
        The string each servo winds, servo order (innovation columns).
    estimate_max_age_s : float, s
        An estimate older than this at a tick is predicted to the tick
        (:attr:`gyrohost.run.settings.RunSettings.estimate_max_age_s`).

    Attributes
    ----------
    t, t_start : float, s
        Host time of the newest estimate received, and of the filter's start.
    x : ndarray, shape (n,)
        The newest estimate received (the filter's state).
    status : Status
        Its status word.
    tilt_rad : float
        Its plane tilt (NaN without an attitude measure or an estimate).
    body_attitude : tuple of 7 float or None
        Its body attitude, quaternion then roll, pitch, yaw, rad
        (:data:`gyrohost.run.streams.BODY_ATTITUDE`; None without a body frame or an estimate).
    health : dict or None
        The summary's ``estimator`` table (:func:`gyrohost.run.health.health`), once stopped.
    lags_s : list of float, s
        How far the newest estimate was behind each tick while the filter was fed.
    """

    def __init__(self, model, scene_path, config, servo_strings, estimate_max_age_s: float):
        self.model = model
        self.t = self.t_start = float("nan")
        self.x = np.full(0, np.nan)
        self.status = Status(0)
        self.tilt_rad = float("nan")
        self.body_attitude: tuple | None = None
        self.health: dict | None = None
        self.lags_s: list[float] = []  # the estimate behind the loop at each fed tick, s
        self.log = None
        self._streams: dict = {}
        self._batch: list = []
        self._fault: BaseException | None = None
        self._ready = False
        ctx = multiprocessing.get_context("spawn")
        self._conn, child = ctx.Pipe()
        args = (child, str(scene_path), config, list(servo_strings), estimate_max_age_s)
        self._proc = ctx.Process(target=_serve, args=args, name="gyrotens-ekf", daemon=True)
        # a Ctrl-C to the process group while the child's interpreter starts would end it with
        # a traceback; it is born with the interrupts blocked (the parent's one held meanwhile)
        with InterruptsHeld(), InterruptsBlocked():
            self._proc.start()
        self._started_s = time.monotonic()
        child.close()

    # --- the loop's side of the filter ------------------------------------------------------
    def ready(self) -> bool:
        """Whether the child has built its model (never waits).

        Raises
        ------
        EstimatorProcessError
            The child failed to build it, or is not ready :data:`READY_TIMEOUT_S` after its
            start.
        """
        self._receive()
        if self._fault is not None:
            raise self._fault
        if not self._ready and time.monotonic() - self._started_s > READY_TIMEOUT_S:
            raise EstimatorProcessError(
                f"estimator process: not ready within {READY_TIMEOUT_S:g} s of its start"
            )
        return self._ready

    def start(self, log, x0, t0_s: float) -> None:
        """Start the filter (once :meth:`ready`) at ``x0`` (n,) at host time ``t0_s``; its rows
        go to ``log``."""
        self.log = log
        self.t = self.t_start = float(t0_s)
        self.x = np.asarray(x0, float)
        self._batch.append(("start", self.x, self.t))

    def fuse_imu(self, t_s, omega_rad_s, accel_m_s2, euler_rad) -> None:
        self._batch.append(("fuse_imu", t_s, omega_rad_s, accel_m_s2, euler_rad))

    def fuse_wheels(self, t_s, omega_rad_s) -> None:
        self._batch.append(("fuse_wheels", t_s, omega_rad_s))

    def fuse_servos(self, t_s, lengths_m, strings) -> None:
        self._batch.append(("fuse_servos", t_s, lengths_m, strings))

    def set_input(self, rest_length_m, t_s=None, wheel_speed_rad_s=None) -> None:
        self._batch.append(("set_input", rest_length_m, t_s, wheel_speed_rad_s))

    def tick(self, t_s: float) -> None:
        """The tick at host time ``t_s``: the estimate logged (predicted to ``t_s`` first when
        older than ``estimate_max_age_s``)."""
        self._batch.append(("tick", t_s))

    def truth(self, t_s: float, N, omega_rad_s, rest_m) -> None:
        """A truth sample of the simulated rig, scored against the estimate
        (:meth:`gyrohost.run.health.TruthScore.truth`)."""
        self._batch.append(("truth", t_s, N, omega_rad_s, rest_m))

    def exchange(self, now_s: float = math.nan, max_lag_s: float = math.inf) -> None:
        """Send this tick's calls; write the rows received since, take the newest estimate.

        Parameters
        ----------
        now_s : float, s
            Host time of the tick.
        max_lag_s : float, s
            The newest estimate may be this far behind ``now_s``.

        Raises
        ------
        EstimatorError
            The filter failed in the child (raised once; later calls only write rows).
        EstimatorProcessError
            The child is gone, its pipe broke, or the estimate lags more than ``max_lag_s``.
        """
        self._flush()
        self._receive()
        fault, self._fault = self._fault, None
        if fault is not None:
            raise fault
        if math.isfinite(max_lag_s):  # fed: the lag is the loop's to watch
            self.lags_s.append(now_s - self.t)
        if now_s - self.t > max_lag_s:
            raise EstimatorProcessError(
                f"the estimate is {now_s - self.t:.3f} s behind the loop (limit {max_lag_s:g} s):"
                " the host is too slow for the estimator in real time"
            )

    def lag_table(self) -> dict:
        """Median, 99th percentile and largest lag of the estimate behind the loop's ticks, s
        (empty before the filter was fed)."""
        if not self.lags_s:
            return {}
        lags = np.array(self.lags_s)
        return {"median": float(np.median(lags)), "p99": float(np.percentile(lags, 99)),
                "max": float(lags.max())}  # fmt: skip

    def stop(self, timeout_s: float = STOP_TIMEOUT_S) -> tuple[bool, str]:
        """Let the child finish what it was sent, write its rows, take its health table and
        end it; returns (finished, what happened) for the safe state's step list."""
        if self.log is None:  # never fed: the pipe's end ends the child at once
            self._conn.close()
            self._end()
            return True, "never started"
        try:
            if self.health is None and self._proc.is_alive():
                self._batch.append(("stop",))
                self._flush()
                deadline = time.monotonic() + timeout_s
                while self.health is None and time.monotonic() < deadline:
                    self._receive(0.1)
        finally:
            self._end()
        if self.health is None:
            return False, (
                f"stopped without its summary within {timeout_s:g} s; the estimate's log ends "
                f"at t = {self.t:.3f} s"
            )
        failed = "" if self._fault is None else f" (it had failed: {self._fault})"
        return True, f"every sample taken, the estimate ends at t = {self.t:.3f} s{failed}"

    def _end(self) -> None:
        self._proc.join(2.0)
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(1.0)
        self._conn.close()

    # --- the pipe ----------------------------------------------------------------------------
    def _flush(self) -> None:
        """Send the calls made since the last message, as one message."""
        if self._batch:
            batch, self._batch = self._batch, []
            self._send(batch)

    def _send(self, batch) -> None:
        try:
            with InterruptsHeld():  # a message is sent whole or not at all
                self._conn.send(batch)
        except _PIPE_ERRORS as exc:
            raise self._gone("cannot send", exc) from exc

    def _receive(self, timeout_s: float = 0.0) -> None:
        try:
            while self._conn.poll(timeout_s):
                with InterruptsHeld():
                    replies = self._conn.recv()
                for reply in replies:
                    self._take(*reply)
                timeout_s = 0.0
        except _PIPE_ERRORS as exc:
            raise self._gone("the pipe ended", exc) from exc

    def _gone(self, what: str, exc: BaseException) -> EstimatorProcessError:
        self._proc.join(1.0)  # a child that died: its exit code (-9 killed) says why
        return EstimatorProcessError(
            f"estimator process: {what} ({exc!r}; exit code {self._proc.exitcode})"
        )

    def _take(self, kind: str, *body) -> None:
        if kind == "row":
            name, values = body
            self._streams[name].write(*values)
        elif kind == "estimate":
            self.t, status, self.tilt_rad, self.body_attitude, x = body
            self.status, self.x = Status(status), np.asarray(x)
        elif kind == "open":
            name, columns, text_columns, description = body
            self._streams[name] = self.log.stream(name, columns, text_columns, description)
        elif kind == "ready":
            self._ready = True
        elif kind == "fault":
            self._fault = body[0]
        elif kind == "health":
            self.health = body[0]


def start_state(model, omega_rad_s, lengths_m: dict) -> np.ndarray:
    """The filter's start as ``gyrotens replay`` takes it: the scene's initial state, the wheel
    speeds (rad/s, board order; the scene's wheels first) and the strings' lengths (m, by string
    name; a string without a servo read keeps the scene's rest length)."""
    from gyrohost.estimator.layout import from_model_state, layout_of

    x0 = from_model_state(model, model.initial_state(), model.input_at(0.0))
    layout = layout_of(model)
    x0[layout.omega] = np.asarray(omega_rad_s, float)[: layout.n_wheels]
    strings = [s.name for s in model.scene.strings]
    for name, length_m in lengths_m.items():
        x0[layout.rest.start + strings.index(name)] = length_m
    return x0


_SOURCES = {
    "fuse_imu": tuple(m.SOURCE for m in IMU_FUSIONS),
    "fuse_wheels": (fuse_wheels.SOURCE,),
    "fuse_servos": (fuse_servos.SOURCE,),
}
"""The filter's calls that fuse a sample, and the sources each one feeds."""


class _RowsOut:
    """The child's stand-in for the run's log: opened streams and rows, queued for the parent."""

    def __init__(self):
        self.items: list = []

    def stream(self, name, columns, text_columns=(), description=""):
        self.items.append(("open", name, list(columns), list(text_columns), description))
        return _StreamOut(self, name)

    def take(self) -> list:
        items, self.items = self.items, []
        return items


class _StreamOut:
    def __init__(self, out: _RowsOut, name: str):
        self.out, self.name = out, name

    def write(self, *values) -> None:
        plain = [v.item() if isinstance(v, np.generic) else v for v in values]
        self.out.items.append(("row", self.name, plain))


class _Filter:
    """The child's filter with its estimate and innovation writers."""

    def __init__(self, model, config, servo_strings, x0, t0_s, out, max_age_s):
        from gyrohost.control.attitude import attitude_of, body_frame_of
        from gyrohost.estimator.ekf import TensegrityEKF
        from gyrohost.run.streams import EstimateWriter, InnovationWriter

        self.innovations = InnovationWriter(out, servo_strings)
        self.ekf = TensegrityEKF(model, config, x0=x0, t0_s=t0_s, log=self.innovations)
        self.estimates = EstimateWriter(out, self.ekf, attitude_of(model), body_frame_of(model))
        self.horizon = FusionHorizon(self.ekf, max_age_s)  # samples in the order taken
        self.skipped = 0  # samples left unfused to catch up

    def call(self, kind: str, args) -> tuple | None:
        """One call of the loop; the estimate's reply after a tick."""
        ekf = self.ekf
        if kind == "tick":
            self.horizon.tick(args[0])
            tilt, body = self.estimates.write(ekf.t)
            return ("estimate", ekf.t, int(ekf.status), tilt, body, ekf.x.tolist())
        if kind == "truth":
            self.estimates.score.truth(*args)
        elif kind in FUSIONS:
            self.horizon.sample(kind, args)
        else:
            getattr(ekf, kind)(*args)  # set_input
        return None

    def skip(self, kind: str, t_s: float) -> None:
        """Leave a sample at ``t_s`` unfused (catching up); its sources are not silent."""
        self.skipped += 1
        for source in _SOURCES[kind]:
            self.ekf.monitors[source].heard(t_s)

    def health(self) -> dict:
        from gyrohost.run.health import health

        return {
            **health(self.innovations.tally, self.estimates.score),
            "not_fused_behind": self.skipped,
            "sources": {name: m.counters() for name, m in self.ekf.monitors.items()},
        }


def _serve(conn, scene_path: str, config, servo_strings, max_age_s: float) -> None:
    """Child process: build the model, then run the filter on the calls the parent sends."""
    from gyrotensegrity import Model, load_scene

    ignore_interrupts()  # the parent stops the child once the rig is safe
    unblock_interrupts()  # born blocked (EstimatorProcess): now ignored, they can come
    os.nice(NICE)
    try:
        try:
            model = Model(load_scene(scene_path))
        except Exception as exc:  # reported to the parent, which raises it
            conn.send([("fault", EstimatorProcessError(f"estimator process: {exc!r}"))])
            return
        conn.send([("ready",)])
        with heap_frozen():
            _Child(conn, model, config, servo_strings, max_age_s).serve()
    except (EOFError, OSError):  # the parent closed the pipe (it ended the run) or is gone
        return


class _Child:
    """The child's loop: the parent's calls in order, the filter's rows and estimates back.

    When more than :attr:`MAX_BEHIND_TICKS` ticks wait (a CPU too slow or too busy), the
    samples of all but the newest are left unfused and only the newest tick's estimate is
    logged, so the estimate catches up instead of falling ever further behind (as the loop
    fuses only the newest samples of a late tick).
    """

    MAX_BEHIND_TICKS = 5

    def __init__(self, conn, model, config, servo_strings, max_age_s):
        self.conn, self.model, self.config = conn, model, config
        self.servo_strings, self.max_age_s = servo_strings, max_age_s
        self.parent = os.getppid()
        self.calls: deque = deque()
        self.ticks = 0  # tick calls waiting
        self.out, self.filter, self.failed = _RowsOut(), None, False

    def serve(self) -> None:
        while True:
            if not self.calls and not self.conn.poll(1.0):
                if os.getppid() != self.parent:
                    return  # the parent is gone
                continue
            while self.conn.poll(0.0):  # keep the parent's pipe empty while behind
                batch = self.conn.recv()
                self.ticks += sum(1 for c in batch if c[0] == "tick")
                self.calls.extend(batch)
            kind, *args = self.calls.popleft()
            self.ticks -= kind == "tick"
            if kind == "stop":
                if self.filter is not None and not self.failed:
                    self.filter.horizon.flush()
                health = self.filter.health() if self.filter else None
                self.conn.send([*self.out.take(), ("health", health)])
                return
            if not self.failed and not self._skipped(kind, args):
                self._call(kind, args)

    def _skipped(self, kind: str, args) -> bool:
        behind = self.ticks >= self.MAX_BEHIND_TICKS
        if behind and kind in _SOURCES and self.filter is not None:
            self.filter.skip(kind, args[0])
        return behind and (kind == "tick" or kind in _SOURCES)

    def _call(self, kind: str, args) -> None:
        try:
            if kind == "start":
                self.filter = _Filter(
                    self.model, self.config, self.servo_strings, *args, self.out, self.max_age_s
                )
                return
            reply = self.filter.call(kind, args)
        except Exception as exc:  # the filter cannot go on: the parent ends the run
            self.failed = True
            self.conn.send([*self.out.take(), ("fault", _picklable(exc))])
            return
        if reply is not None:
            self.conn.send([*self.out.take(), reply])


def _picklable(exc: BaseException) -> BaseException:
    """``exc``, or a :class:`RunError` with its text where it would not cross the pipe."""
    import pickle

    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:
        return RunError(f"estimator: {type(exc).__name__}: {exc}")
