"""The experiment sequence on the rig (hardware or simulated), as explicit phases.

::

    check      schedule against every servo's limits, strings against the servos  (nothing moves)
    connect    IMU sample, wheel-board handshake (protocol version; faults latched before the
               run cleared and logged), servo pings (MX-12W); the measured state against the
               scene's initial state (run/start_check.py: refused outside tolerances, exit 2)
    hold       servos: multi-turn mode, torque on, hold the present position
    spinup     wheels to the scene's spins; wait for steady speed (time-out)
    lead_in    the simulated rig's held truth released; estimator started from the steady
               state, schedule at its first sample
    schedule   the schedule played at the host rate (100 Hz), every device sample fused
    settle     schedule held at its last sample, estimator running
    rampdown   wheels stopped, wait until they are slow (bounded), servos held: the safe state

Every exit path, a normal end included, goes through one routine, :meth:`RunLoop.safe_state`
(:mod:`gyrohost.run.safe_state`). Ctrl-C (``KeyboardInterrupt``), a device fault (a driver
error, a reader's :class:`~gyrohost.run.errors.DeviceFault`), a limit breach, an estimator
fault and a time-out all end there; :class:`~gyrohost.run.settings.RunResult` then carries a
non-zero exit status and the reason.

Device I/O runs in background threads (:mod:`gyrohost.run.devices`); the loop thread only drains
their queue (:mod:`gyrohost.run.dispatch`), fuses, commands and logs
(:mod:`gyrohost.run.streams`), and sleeps to the next tick of a fixed grid
(:mod:`gyrohost.run.ticker`).
"""

import math
import queue
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from gyrohost.control.attitude import attitude_of, body_frame_of
from gyrohost.control.closed_loop import ekf_estimate
from gyrohost.control.maneuver import Maneuver
from gyrohost.control.schedule import Schedule
from gyrohost.drivers import wheelproto as wp
from gyrohost.estimator.config import EstimatorConfig, for_rig
from gyrohost.estimator.imu_model import ImuGeometry
from gyrohost.gcfreeze import heap_frozen
from gyrohost.run.connect import connect_devices, with_ports
from gyrohost.run.devices import ImuReader, ServoWorker, failure_text
from gyrohost.run.dispatch import (
    Dispatcher,
    GoalHandler,
    ImuHandler,
    ServoHandler,
    WheelHandler,
)
from gyrohost.run.errors import RunError, StartStateRefused
from gyrohost.run.estimation import EstimatorProcess, start_state
from gyrohost.run.health import fails_run
from gyrohost.run.limits import CommandHistory, check_limits, check_schedule
from gyrohost.run.log import RunLog
from gyrohost.run.mcap import McapSink
from gyrohost.run.replan_hold import ReplanHold
from gyrohost.run.safe_state import attempt, ignore_interrupts, reach_safe_state
from gyrohost.run.settings import RunResult, RunSettings
from gyrohost.run.start_check import check_start_state
from gyrohost.run.streams import ReplanWriter, TruthProbe, body_summary, open_run_streams
from gyrohost.run.summary import run_meta, run_summary
from gyrohost.run.ticker import Readout, Ticker, status_words
from gyrohost.sigint import InterruptsRaised, exit_status, signal_name
from gyrotensegrity import Model, load_scene


class RunLoop:
    """One run of a schedule on a rig.

    Parameters
    ----------
    config : RigConfig
        Device ports (real devices or ptys), servos, IMU; ``scene_path`` gives the model.
    schedule : Schedule or Maneuver
        A fixed schedule, or a planned tilt maneuver (:class:`gyrohost.control.maneuver.
        Maneuver`, planned on the same scene): its first plan is played; closed loop, every
        tick of the schedule phase hands it the EKF's estimate and plays what it returns.
        Every plan goes to the ``replan`` stream.
    log_folder : path
        New log folder (must not hold a log).
    settings : RunSettings, optional
    estimator : EstimatorConfig, optional
        The EKF's configuration (default: :func:`gyrohost.estimator.config.for_rig` of
        ``config``); its IMU attachment must name nodes of the scene (else
        :class:`~gyrohost.estimator.EstimatorConfigError` here, before anything moves).
    rig : RigProcess, optional
        The simulated rig: its truth samples go to the ``truth`` stream, its statistics to the
        summary.
    on_tick : callable(loop, phase, t_s), optional
        Called at the end of every tick (tests inject faults or Ctrl-C from here).
    progress : callable(phase, t_s, fraction, readout), optional
        Called every tick; ``fraction`` of the schedule played, in [0, 1]; ``readout`` the
        estimated tilt, wheel speeds and estimator status (:meth:`readout`).
    notify : callable(str), optional
        Shows a line the user must see during the run (wheel-board faults found latched before
        it and cleared); default: printed on stderr.
    meta : dict, optional
        Extra items for ``meta.json`` (command line, ...).
    live : log sink, optional
        Every row to a live view too (:class:`gyrohost.run.live.LiveView`), beside the CSV
        streams and the MCAP file ``run.mcap`` every run writes.
    """

    def __init__(
        self,
        config,
        schedule: Schedule | Maneuver,
        log_folder,
        settings: RunSettings | None = None,
        estimator: EstimatorConfig | None = None,
        rig=None,
        on_tick=None,
        progress=None,
        notify=None,
        meta: dict | None = None,
        live=None,
    ):
        self.config = config
        self.maneuver = schedule if isinstance(schedule, Maneuver) else None
        self.schedule = schedule.schedule if self.maneuver else schedule
        self.settings = settings or RunSettings.for_rig(config)
        self.estimator_config = estimator or for_rig(config)
        self.rig = rig
        self.on_tick = on_tick
        self.progress = progress
        self.notify = notify
        self.heard: list[str] = []
        """Interrupts a signal handler noted, for the next event to log."""
        self.model = Model(load_scene(config.scene_path))
        self.schedule.bind(self.model)
        self.wheel_index = self.schedule.bind_wheels(self.model)  # board wheel i = scene wheel i
        self.tilt = attitude_of(self.model)
        self.body = body_frame_of(self.model)
        ImuGeometry(self.model, self.estimator_config)  # attached to nodes of this scene?
        self.strings = [s.name for s in self.model.scene.strings]
        self.servo_strings = [s.string or s.name for s in config.servos.servo]
        self.rest0 = np.array([s.rest_length(0.0) for s in self.model.scene.strings])
        self.spins = np.zeros(wp.N_WHEELS)
        wheels = [self.model.scene.bars[b].wheel for b in self.model.wheel_bars]
        self.spins[: len(wheels)] = [w.spin0 for w in wheels]
        self.n_wheels = len(wheels)
        self.wheel_commands = CommandHistory(self.settings.wheel_command_memory_s)
        self.log_folder = Path(log_folder)
        self.extra_meta = meta or {}
        self.sinks = [McapSink(self.model.scene), *([live] if live is not None else [])]
        self.phase = "check"
        self.queue: queue.Queue = queue.Queue()
        self.ticker = Ticker(self.settings.rate_hz)
        self.dispatcher = self.servo_handler = None
        self.imu = self.wheels = self.servos = None
        self.readers: list = []
        self.wheel_reader = self.servo_worker = None
        self.estimator: EstimatorProcess | None = None
        self.ekf = None  # the estimator while it is fed samples (None from the safe state on)
        self.truth = None
        self.latest_tilt = math.nan
        self.final: dict = {}
        self.omega_cmd = np.zeros(wp.N_WHEELS)
        self.rest_cmd = self.rest0.copy()
        self.t_schedule_s = math.nan
        self.estimate = self.replans = self.streams = None
        self._followed_t_s = math.nan
        closed = self.maneuver is not None and self.maneuver.target.closed_loop
        self.replan_hold = (
            ReplanHold(self.maneuver.target.period_s, self.notice, self.event) if closed else None
        )
        self._command_failed = False  # a command or heartbeat failed in the safe state

    # --- the sequence -------------------------------------------------------------------------
    def run(self) -> RunResult:
        """Run the whole sequence; never leaves the rig anywhere but in the safe state.

        Raises
        ------
        ScheduleRefused
            Before anything is opened or moved.
        """
        check_schedule(self.schedule, self.config.servos.servo, self.config.run,
                       self.settings.max_schedule_s)  # fmt: skip
        with InterruptsRaised():  # SIGTERM, SIGHUP: as Ctrl-C
            self.log = RunLog(self.log_folder, run_meta(self), self.sinks)
            try:
                # frozen before any device thread runs: the collection holds the interpreter
                # for its whole length (0.1 s in a small process, longer in a big one), and a
                # wheel board whose heartbeat stops for HEARTBEAT_MS latches its fail-safe
                with heap_frozen():
                    self._open_streams()
                    self._sequence()
                reason, status = "completed", 0
            except KeyboardInterrupt as exc:  # Ctrl-C, SIGTERM, SIGHUP
                reason, status = f"interrupted ({signal_name(exc)})", exit_status(exc)
            except StartStateRefused as exc:  # a user error: put the rig back
                reason, status = f"start state refused: {exc}", 2
            except Exception as exc:  # every fault ends in the safe state, then is reported
                reason, status = failure_text(exc), 1
            with ignore_interrupts(self, "the safe state and the summary"):
                summary = self._end(reason)
        if self.log.failure is not None and status == 0:
            status = 1  # the run completed, its log did not
        if fails_run(summary.get("estimator", {})) and status == 0:
            status = 1  # the run completed, its estimate did not hold
        return RunResult(reason == "completed", reason, status, self.log_folder, summary)

    def _end(self, reason: str) -> dict:
        """The safe state, then the log closed and the summary written: each step attempted
        whatever the others raised; returns the summary (in ``meta.json`` if it could be
        written, its ``safe_state.steps`` saying what failed)."""
        self.event("end", reason)
        out = {"reason": reason, "steps": []}
        if self.maneuver is not None:
            attempt(self, out, "join re-planner", self._join_maneuver)
        safe = self.safe_state(reason)
        safe["steps"][:0] = out["steps"]
        if self.estimator is not None:
            attempt(self, safe, "stop estimator", self.estimator.stop)
        summary = {"reason": reason, "safe_state": safe}
        attempt(self, safe, "summary", lambda: self._summarise(summary, reason, safe))
        attempt(self, safe, "close log", lambda: self._close_log(safe))
        attempt(self, safe, "write summary", lambda: self._write_summary(summary))
        return summary

    def _join_maneuver(self) -> tuple[bool, str]:
        self.maneuver.join()
        self.replans.write(self.maneuver.records)
        return True, "joined"

    def _summarise(self, summary: dict, reason: str, safe: dict) -> tuple[bool, str]:
        summary.update(run_summary(self, reason, safe))
        return True, "made"

    def _close_log(self, safe: dict) -> tuple[bool, str]:
        """Close every stream; a write refused during the run is reported here."""
        self.log.close()
        if self.log.failure is None:
            return True, "every row written"
        safe["log_failure"] = self.log.failure
        safe["log_ends_t_s"] = self.log.last_t_s
        return False, f"{self.log.failure}: the log ends {self.log.ends_at()}"

    def _write_summary(self, summary: dict) -> tuple[bool, str]:
        self.log.update_meta(summary=summary)
        return True, "in meta.json"

    def spawn_estimator(self) -> None:
        """Start the estimator's child process, once: it imports and builds its model while
        the devices connect and the wheels spin up (and, on the simulated rig, while the rig's
        own process starts: :func:`gyrohost.run.simulated.run_simulated`). A child the run never
        takes up is ended by :meth:`run`'s safe state, or by :meth:`end_estimator`."""
        if self.estimator is None:
            self.estimator = EstimatorProcess(
                self.model,
                self.config.scene_path,
                self.estimator_config,
                self.servo_strings,
                self.settings.estimate_max_age_s,
            )

    def end_estimator(self) -> None:
        """End the estimator's child if the run did not (a run that never began)."""
        if self.estimator is not None:
            self.estimator.stop()

    def attach_rig(self, rig) -> None:
        """Run on the started simulated rig ``rig`` (a ``RigProcess``): its ptys as the ports,
        its truth streamed to the log and the estimator's score."""
        self.config = with_ports(self.config, rig.paths)
        self.rig = rig

    def _sequence(self) -> None:
        self._enter("connect")
        self.spawn_estimator()
        connect_devices(self)
        check_start_state(self)
        self._enter("hold")
        self.servos.configure()
        self._start_readers()
        self._enter("spinup")
        self._spin_up()
        self._enter("lead_in")
        if self.rig is not None:  # a held truth (motor reactions) let go after its spin-up
            self.event("rig", self.rig.command("release"))
        self._start_estimator()
        self._ticks(self.settings.lead_in_s)
        self._enter("schedule")
        self.t_schedule_s = self.now()
        self._ticks(self.schedule.t_end)
        self._record_tilts("tilt_end")
        self._enter("settle")
        self._ticks(self.settings.settle_s)
        self._record_tilts("tilt_settled")

    def _enter(self, phase: str) -> None:
        self.phase = phase
        self.event("phase", phase)

    def _record_tilts(self, key: str) -> None:
        """The newest estimate's tilt and the truth's at its time, for the summary (D-bar
        scenes); its body attitude and the truth's (``attitude_end``, ``attitude_settled``:
        scenes with a body frame)."""
        if self.estimator.body_attitude is not None:
            truth = None if self.truth is None else self.truth.body_at(self.estimator.t)
            name = key.replace("tilt", "attitude")
            self.final[name] = body_summary(self.estimator.body_attitude, truth)
        if self.tilt is None:
            return
        self.final[f"{key}_estimate_rad"] = self.latest_tilt
        if self.truth is not None:  # at the estimate's time: it lags the loop by a tick or two
            self.final[f"{key}_truth_rad"] = self.truth.tilt_at(self.estimator.t)

    def safe_state(self, reason: str) -> dict:
        """Ramp the wheels down, hold the servos, log the outcome; returns what was reached
        (:func:`gyrohost.run.safe_state.reach_safe_state`)."""
        return reach_safe_state(self, reason)

    # --- devices ------------------------------------------------------------------------------
    def _start_readers(self) -> None:
        s = self.settings
        self.servo_worker = ServoWorker(self.servos, self.queue, s.servo_rate_hz)
        self.readers = [
            ImuReader(self.imu, self.queue, s.imu_silence_s),
            self.wheel_reader,
            self.servo_worker,
        ]
        for r in self.readers:
            r.start()
        self.ticker.regrid()

    def _wheel_command(self, t_rel_s: float) -> np.ndarray:
        """Board wheel speeds (4,) rad/s at schedule time ``t_rel_s``: the scene's spins, the
        scheduled wheels' speeds in their place."""
        omega = self.spins.copy()
        omega[self.wheel_index] = self.schedule.wheel_speeds(t_rel_s)
        return omega

    def _spin_up(self) -> None:
        s = self.settings
        self.omega_cmd = self._wheel_command(0.0)
        self.wheels.set_speeds(list(self.omega_cmd))
        deadline = self.now() + s.spinup_timeout_s
        steady_since = None
        while True:
            self.tick()
            tel = self.wheel_reader.latest
            err = np.max(np.abs(np.array(tel.omega_rad_s) - self.omega_cmd)) if tel else math.inf
            now = self.now()
            if err <= s.steady_tolerance_rad_s:
                steady_since = now if steady_since is None else steady_since
                if now - steady_since >= s.steady_hold_s:
                    self.event("steady", f"wheels within {err:.2f} rad/s of their setpoints")
                    return
            else:
                steady_since = None
            if now > deadline:
                raise RunError(
                    f"spin-up time-out: wheels {err:.2f} rad/s off their setpoints after "
                    f"{s.spinup_timeout_s:g} s"
                )

    def _start_estimator(self) -> None:
        while not self.estimator.ready():  # its model built while the wheels spun up
            self.tick()
        servos = zip(self.servo_strings, self.latest_servos, strict=False)  # none read: scene
        lengths = {name: state.length_m for name, state in servos}
        x0 = start_state(self.model, self.wheel_reader.latest.omega_rad_s, lengths)
        self.estimator.start(self.log, x0, self.now())
        self.log.update_meta(estimator=asdict(self.estimator_config))  # gyrotens replay reads it
        self.ekf = self.estimator
        self.ekf.set_input(self.rest_cmd, wheel_speed_rad_s=self.omega_cmd[: self.n_wheels])
        self.estimate = ekf_estimate(self.ekf)

    @property
    def latest_servos(self) -> list:
        """The newest servo read-back (ServoState per servo; empty before the first)."""
        return self.servo_handler.latest if self.servo_handler is not None else []

    # --- one tick -----------------------------------------------------------------------------
    def now(self) -> float:
        """Host time since the run's time zero, s."""
        return self.ticker.now()

    def _ticks(self, duration_s: float) -> None:
        end = self.now() + duration_s
        while self.now() < end:
            self.tick()

    def tick(self, strict: bool = True) -> None:
        """Wait for the next tick of the grid, then drain, fuse, command, check and log;
        ``strict`` False (the safe state): faults logged, not raised, no limit or hook."""
        start, due = self.ticker.wait()
        cpu0 = time.thread_time()
        n, faults = self.dispatcher.drain(self.ticker.t0_ns, self.ekf)
        for fault in faults:
            if strict:
                raise fault
            self.event("fault", str(fault))
        try:
            self._command(self.now())  # after any fault; stamped when sent
        except Exception as exc:  # the safe state: a port gone; logged once, not every tick
            if strict:
                raise
            if not self._command_failed:
                self.event("fault", f"command: {failure_text(exc)}")
            self._command_failed = True
        if self.wheels is not None:
            try:  # from the thread that decides the speeds: a loop that stalls stops the wheels
                self.wheels.heartbeat()
            except OSError:
                if strict:
                    raise
                # the safe state: its "stop wheels" step reports a dead port
        if self.ekf is not None:
            self.ekf.tick(start)
        if self.truth is not None:
            self._write_truth(strict)
        if self.estimator is not None and self.estimator.log is not None:
            self._exchange(start, strict)
        if strict:
            self.log.check()  # a refused write ends the run here, wherever it happened
            tel = self.wheel_reader.latest if self.wheels is not None else None
            self.wheel_commands.add(start, float(np.max(np.abs(self.omega_cmd))))
            peak = self.wheel_commands.peak_before(self._arrival_s(start))
            check_limits(self.settings, peak, tel, self.latest_servos,
                         self.latest_tilt, self.ekf)  # fmt: skip
        cpu = time.thread_time() - cpu0
        lag_s = start - self.ekf.t if self.ekf is not None else math.nan
        self.streams.loop.write(start, start - due, self.now() - start, cpu, n, lag_s, self.phase)
        if self.progress is not None:
            self.progress(self.phase, start, self._played(start), self.readout())
        if strict and self.on_tick is not None:
            self.on_tick(self, self.phase, start)

    def _arrival_s(self, default_s: float) -> float:
        """Host time (s) the newest telemetry frame arrived (``default_s`` without one)."""
        ns = self.wheel_reader.latest_ns if self.wheel_reader is not None else None
        return default_s if ns is None else (ns - self.ticker.t0_ns) * 1e-9

    def readout(self) -> Readout:
        """Estimated tilt, measured wheel speeds, the estimator's status and the estimated body
        attitude now."""
        tel = self.wheel_reader.latest if self.wheel_reader is not None else None
        body = None if self.ekf is None else self.ekf.body_attitude
        return Readout(
            self.latest_tilt,
            None if tel is None else tuple(tel.omega_rad_s),
            "off" if self.ekf is None else status_words(self.ekf.status),
            None if body is None else body[4:],
        )

    def _exchange(self, t_s: float, strict: bool) -> None:
        """The tick's calls to the estimator's process, its rows into the log; the newest
        estimate's tilt, and a new estimate to the maneuver. ``strict`` False (the safe state):
        its faults logged, not raised."""
        est = self.estimator
        try:  # a lagging estimate ends the run while the limits act on it
            est.exchange(t_s, self.settings.estimator_max_lag_s if self.ekf else math.inf)
        except Exception as exc:
            if strict and self.estimate_required:
                raise
            if strict:
                self._without_estimator(exc)
            else:
                self.event("fault", f"estimator: {failure_text(exc)}")
        self.latest_tilt = est.tilt_rad if self.ekf is not None else math.nan
        new = est.t != self._followed_t_s
        if strict and new and self.phase == "schedule" and self.maneuver is not None:
            self._followed_t_s = est.t
            self._follow_estimate(t_s)

    @property
    def estimate_required(self) -> bool:
        """Whether the run needs its estimate: every run but an identification run (whose
        scene is the one still to be identified) on which nothing acts on the estimate (no
        tilt limit, no maneuver)."""
        return (
            self.schedule.purpose != "identification"
            or math.isfinite(self.settings.max_tilt_rad)
            or self.maneuver is not None
        )

    def _without_estimator(self, exc: BaseException) -> None:
        """The estimator of a run that does not need it failed (:attr:`estimate_required`):
        told, and the recording goes on unfused; the estimate's log ends here."""
        self.ekf = None
        self.notice(
            f"estimator: {failure_text(exc)}; nothing acts on the estimate of this "
            "identification run: the recording goes on without it"
        )

    def _follow_estimate(self, now_s: float) -> None:
        """Closed loop: the estimate to the maneuver at the tick ``now_s``, its schedule from
        the next tick on; not while the IMU no longer corrects the estimate
        (:class:`.replan_hold.ReplanHold`)."""
        t_s, x = self.estimate()
        if self.replan_hold is not None and not self.replan_hold.follow(t_s, self.estimator.status):
            return
        t0 = self.t_schedule_s
        self.schedule = self.maneuver.update(t_s - t0, x, now_s - t0)
        self.replans.write(self.maneuver.records)

    def _write_truth(self, strict: bool) -> None:
        """The simulated rig's truth to its stream; in the safe state a failing probe (whatever
        it raises) is logged and dropped, so the rest of the safe state goes on."""
        try:
            self.truth.write(self.ekf)  # scored by the estimator while it is fed
        except Exception as exc:
            if strict:
                raise
            self.event("fault", f"truth probe: {failure_text(exc)}")
            self.truth = None

    def _played(self, t_s: float) -> float:
        if self.phase in ("settle", "rampdown"):
            return 1.0
        if self.phase != "schedule":
            return 0.0
        return min((t_s - self.t_schedule_s) / max(self.schedule.t_end, 1e-9), 1.0)

    def _command(self, t_s: float) -> None:
        if self.phase in ("schedule", "settle", "lead_in"):
            t_rel = t_s - self.t_schedule_s if self.phase != "lead_in" else 0.0
            rest = self.rest0.copy()
            rest[self.schedule.bind(self.model)] = self.schedule(t_rel)
            self.rest_cmd = rest
            goals = {
                s.name: rest[self.strings.index(name)]
                for s, name in zip(self.config.servos.servo, self.servo_strings, strict=True)
                if name in self.schedule.names
            }
            self.servo_worker.command(goals)
            omega = self._wheel_command(t_rel)
            if not np.array_equal(omega, self.omega_cmd):  # one frame, no reply awaited
                self.wheels.set_speeds(list(omega), confirm=False)
                self.omega_cmd = omega
            if self.ekf is not None:  # the wheels' from the tick on; the rests' as sent
                self.ekf.set_input(None, t_s, self.omega_cmd[: self.n_wheels])
        self.streams.command.write(t_s, *self.rest_cmd, *self.omega_cmd)

    # --- the log ------------------------------------------------------------------------------
    def _open_streams(self) -> None:
        log = self.log
        self.ticker.start()
        self.streams = open_run_streams(log, self.strings, self.servo_strings)
        self.servo_handler = ServoHandler(self.streams.servos, self.strings, self.servo_strings)
        handlers = [
            ImuHandler(self.streams.imu, self.estimator_config),
            WheelHandler(self.streams.wheels, len(self.model.wheel_bars), self.estimator_config),
            self.servo_handler,
            GoalHandler(self.streams.servo_goals, self.strings, self._wound(), self.rest0),
        ]
        self.dispatcher = Dispatcher(self.queue, handlers, self.settings.max_fused_per_tick)
        if self.rig is not None:
            self.truth = TruthProbe(self.rig, log, self.tilt, self.ticker.t0_ns, self.body)
        if self.maneuver is not None:
            self.replans = ReplanWriter(log, lambda: self.t_schedule_s)
            self.replans.write(self.maneuver.records)  # the first plan, made before the run

    def _wound(self) -> dict:
        """Servo name -> the scene string it winds, for the servos that wind one."""
        pairs = zip(self.config.servos.servo, self.servo_strings, strict=True)
        return {s.name: string for s, string in pairs if string in self.strings}

    def notice(self, message: str) -> None:
        """A line the user must see now: to ``notify`` (else stderr) and the events stream."""
        (self.notify or _stderr_line)(message)
        self.event("notice", message)

    def event(self, kind: str, message: str) -> None:
        """Append one row to the ``events`` stream (commas become semicolons), after the
        interrupts noted since the last one."""
        if self.streams is None:  # none before the log is open
            return
        while self.heard:
            self._event_row("interrupt", self.heard.pop(0))
        self._event_row(kind, message)

    def _event_row(self, kind: str, message: str) -> None:
        text = " ".join(str(message).replace(",", ";").split())
        self.streams.events.write(self.now(), kind, text)


def _stderr_line(message: str) -> None:
    print(message, file=sys.stderr)
