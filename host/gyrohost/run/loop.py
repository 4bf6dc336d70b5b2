"""The experiment sequence on the rig (hardware or simulated), as explicit phases.

::

    check      schedule against every servo's limits, strings against the servos  (nothing moves)
    connect    IMU sample, wheel-board handshake (protocol version; faults latched before the
               run cleared and logged), servo pings (MX-12W)
    hold       servos: multi-turn mode, torque on, hold the present position
    spinup     wheels to the scene's spins; wait for steady speed (time-out)
    lead_in    estimator started from the steady state, schedule at its first sample
    schedule   the schedule played at the host rate (100 Hz), every device sample fused
    settle     schedule held at its last sample, estimator running
    rampdown   wheels stopped, wait until they are slow (bounded), servos held: the safe state

Every exit path, a normal end included, goes through one routine, :meth:`RunLoop.safe_state`:
stop all wheels and wait until every measured speed is below ``stop_threshold_rad_s`` (at most
``rampdown_timeout_s``), hold every servo at its present position, and log why. Ctrl-C
(``KeyboardInterrupt``), a device fault (a driver error, a reader's :class:`DeviceFault`), a
limit breach, an estimator fault and a time-out all end there; :class:`RunResult` then carries
a non-zero exit status and the reason.

Device I/O runs in background threads (:mod:`gyrohost.run.devices`); the loop thread only drains a
queue, fuses, commands and logs, and sleeps to the next tick of a fixed grid. Tick timing goes
to the ``loop`` stream and the summary (:class:`gyrohost.run.records.LoopTimer`).
"""

import math
import queue
import signal
import threading
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from gyrohost.control.closed_loop import ekf_estimate
from gyrohost.control.maneuver import Maneuver
from gyrohost.control.schedule import Limits, Schedule
from gyrohost.drivers import wheelproto as wp
from gyrohost.drivers.imu import Bwt61Driver
from gyrohost.drivers.servos import StringServoBus
from gyrohost.drivers.wheelboard import WheelBoard, WheelBoardError
from gyrohost.estimator import TensegrityEKF, config_from_dict
from gyrohost.estimator import streams as cols
from gyrohost.estimator.config import noise_from_rig
from gyrohost.estimator.ekf import Status
from gyrohost.estimator.layout import from_model_state, layout_of
from gyrohost.rig.process import RigProcess, RigProcessError
from gyrohost.run.devices import ImuReader, Sample, ServoWorker, WheelTelemetry
from gyrohost.run.log import RunLog
from gyrohost.run.records import (
    EstimateWriter,
    InnovationWriter,
    LoopTimer,
    ReplanWriter,
    TiltMeter,
    TruthProbe,
    jitter_line,
)
from gyrotensegrity import Model, __version__, load_scene


class RunError(RuntimeError):
    """The run could not go on (time-out, estimator fault); the message says why."""


class LimitBreach(RunError):
    """A measured or estimated value left its limit during the run."""


class ScheduleRefused(ValueError):
    """The schedule breaks a servo limit or names a string no servo winds (nothing moved)."""


@dataclass(frozen=True)
class RunSettings:
    """Timing, thresholds and limits of a run (SI units)."""

    rate_hz: float = 100.0
    servo_rate_hz: float = 25.0
    telemetry_div: int = 20
    """Wheel-board TELEMETRY every this many 1 kHz ticks (20: 50 Hz)."""
    heartbeat_ms: int = 500
    """Wheel-board fail-safe time-out: no frame from the host this long stops the wheels, ms."""
    spinup_timeout_s: float = 10.0
    steady_tolerance_rad_s: float = 1.5
    steady_hold_s: float = 0.3
    lead_in_s: float = 0.5
    settle_s: float = 0.5
    stop_threshold_rad_s: float = 3.0
    """Wheels count as stopped below this speed, or once the board has switched them off."""
    rampdown_timeout_s: float = 5.0
    imu_silence_s: float = 0.5
    wheel_silence_s: float = 0.5
    max_tilt_rad: float = math.inf
    """Largest |tilt| of the estimate, rad; off by default: the simulated D-bar floats free and
    keeps turning after the maneuver (set it on a rig whose supports bound the tilt)."""
    wheel_speed_margin_rad_s: float = 15.0
    max_servo_load: float = 0.95
    max_fused_per_tick: int = 4
    """Samples of one device fused per tick at most (the newest); older ones are only logged."""

    def __post_init__(self):
        for name, value in asdict(self).items():
            if not value > 0:  # NaN fails too
                raise ValueError(f"run settings: {name} must be a positive number, got {value}")


@dataclass
class RunResult:
    """How a run ended.

    Attributes
    ----------
    completed : bool
        The schedule ran to its end (the safe state was then reached as the normal end).
    reason : str
        Why the run ended (``"completed"``, the fault, ``"interrupted (Ctrl-C)"``).
    exit_status : int
        0 completed, 1 fault, limit or time-out, 130 Ctrl-C.
    log_folder : Path
    summary : dict
        Also written to the log's ``meta.json`` under ``summary``.
    """

    completed: bool
    reason: str
    exit_status: int
    log_folder: Path
    summary: dict = field(default_factory=dict)


def check_schedule(schedule: Schedule, servos) -> None:
    """Refuse a schedule that breaks any servo's limits (before anything moves).

    Each scheduled string must be wound by a configured servo; its rest lengths must lie in
    that servo's ``[min_length_m, max_length_m]`` and change no faster than ``max_speed_m_s``.

    Raises
    ------
    ScheduleRefused
        Naming the string, the value and the limit.
    """
    by_string = {s.string or s.name: s for s in servos}
    problems = []
    for i, name in enumerate(schedule.names):
        servo = by_string.get(name)
        if servo is None:
            problems.append(f"{name}: no servo winds this string (servos: {sorted(by_string)})")
            continue
        one = Schedule((name,), schedule.t, schedule.rest_length[:, [i]], schedule.name)
        problems += one.problems(Limits.from_servos([servo]))
    if problems:
        raise ScheduleRefused(
            f"schedule {schedule.name} refused, nothing moved: " + "; ".join(problems)
        )


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
    rig : RigProcess, optional
        The simulated rig: its truth samples go to the ``truth`` stream, its statistics to the
        summary.
    on_tick : callable(loop, phase, t_s), optional
        Called at the end of every tick (tests inject faults or Ctrl-C from here).
    progress : callable(phase, t_s, fraction), optional
        Called every tick; ``fraction`` of the schedule played, in [0, 1].
    meta : dict, optional
        Extra items for ``meta.json`` (command line, ...).
    """

    def __init__(
        self,
        config,
        schedule: Schedule | Maneuver,
        log_folder,
        settings: RunSettings | None = None,
        rig=None,
        on_tick=None,
        progress=None,
        meta: dict | None = None,
    ):
        self.config = config
        self.maneuver = schedule if isinstance(schedule, Maneuver) else None
        self.schedule = schedule.schedule if self.maneuver else schedule
        self.settings = settings or RunSettings()
        self.rig = rig
        self.on_tick = on_tick
        self.progress = progress
        self.model = Model(load_scene(config.scene_path))
        self.schedule.bind(self.model)
        self.tilt = TiltMeter(self.model)
        self.strings = [s.name for s in self.model.scene.strings]
        self.servo_strings = [s.string or s.name for s in config.servos.servo]
        self.rest0 = np.array([s.rest_length(0.0) for s in self.model.scene.strings])
        self.spins = np.zeros(wp.N_WHEELS)
        wheels = [self.model.scene.bars[b].wheel for b in self.model.wheel_bars]
        self.spins[: len(wheels)] = [w.spin0 for w in wheels]
        self.log_folder = Path(log_folder)
        self._extra_meta = meta or {}
        self.phase = "check"
        self.queue: queue.Queue = queue.Queue()
        self.timer = LoopTimer(1.0 / self.settings.rate_hz)
        self.imu = self.wheels = self.servos = None
        self.readers: list = []
        self.wheel_reader = self.servo_worker = None
        self.latest_servos: list = []
        self.skipped: dict[str, int] = {}
        self.ekf = None
        self.estimates = None
        self.truth = None
        self.latest_tilt = math.nan
        self.final: dict = {}
        self.omega_cmd = np.zeros(wp.N_WHEELS)
        self.rest_cmd = self.rest0.copy()
        self.t_schedule_s = math.nan
        self.estimate = self.replans = None
        self._t0_ns = 0
        self._next_due_s = 0.0

    # --- the sequence -------------------------------------------------------------------------
    def run(self) -> RunResult:
        """Run the whole sequence; never leaves the rig anywhere but in the safe state.

        Raises
        ------
        ScheduleRefused
            Before anything is opened or moved.
        """
        check_schedule(self.schedule, self.config.servos.servo)
        with RunLog(self.log_folder, self._meta()) as log:
            self.log = log
            self._open_streams()
            try:
                self._sequence()
                reason, status = "completed", 0
            except KeyboardInterrupt:
                reason, status = "interrupted (Ctrl-C)", 130
            except Exception as exc:  # every fault ends in the safe state, then is reported
                reason, status = f"{type(exc).__name__}: {exc}", 1
            self.event("end", reason)
            if self.maneuver is not None:
                self.maneuver.join()
                self.replans.write(self.maneuver.records)
            safe = self.safe_state(reason)
            summary = self._summary(reason, safe)
            log.update_meta(summary=summary)
        return RunResult(status == 0, reason, status, self.log_folder, summary)

    def _sequence(self) -> None:
        self._enter("connect")
        self._connect()
        self._enter("hold")
        self.servos.configure()
        self._start_readers()
        self._enter("spinup")
        self._spin_up()
        self._enter("lead_in")
        self._start_estimator()
        self._ticks(self.settings.lead_in_s)
        self._enter("schedule")
        self.t_schedule_s = self._now()
        self._ticks(self.schedule.t_end)
        self.final["tilt_end_estimate_rad"] = self.latest_tilt
        if self.truth is not None:
            self.final["tilt_end_truth_rad"] = self.truth.latest_tilt
        self._enter("settle")
        self._ticks(self.settings.settle_s)
        self.final["tilt_settled_estimate_rad"] = self.latest_tilt
        if self.truth is not None:
            self.final["tilt_settled_truth_rad"] = self.truth.latest_tilt

    def _enter(self, phase: str) -> None:
        self.phase = phase
        self.event("phase", phase)

    # --- devices ------------------------------------------------------------------------------
    def _connect(self) -> None:
        cfg, s = self.config, self.settings
        self.imu = Bwt61Driver(cfg.imu.port, baud=cfg.imu.baud, timeout_s=s.imu_silence_s).open()
        first = self.imu.read_sample()
        self.wheel_reader = WheelTelemetry(self.queue, s.wheel_silence_s)
        self.wheels = WheelBoard(cfg.wheelboard.port, on_telemetry=self.wheel_reader.on_telemetry)
        hello = self.wheels.connect()
        before = self.wheels.faults
        self.wheels.clear_faults()  # e.g. HEARTBEAT_LOST latched while no host was connected
        if before:
            self.event("cleared", f"wheel-board faults latched before the run: {before}")
        self.wheel_reader.arm()
        self.wheels.set_param("TELEMETRY_DIV", s.telemetry_div)
        self.wheels.set_param("HEARTBEAT_MS", s.heartbeat_ms)
        speed_max = self.wheels.get_param("SPEED_MAX_MRAD_S") / 1000.0
        if np.max(np.abs(self.spins)) > speed_max:
            raise LimitBreach(
                f"scene spins up to {np.max(np.abs(self.spins)):.2f} rad/s exceed the wheel "
                f"board's SPEED_MAX {speed_max:.2f} rad/s"
            )
        self.servos = StringServoBus(cfg.servos).open()
        models = self.servos.ping_all()
        versions = {
            "wheel_board": hello,
            "servo_models": models,
            "imu_first_sample_temperature_degC": first.temperature_degC,
        }
        self.log.update_meta(devices=versions)
        self.event("versions", f"wheel board fw {hello['fw_major']}.{hello['fw_minor']} "
                   f"protocol v{hello['proto_version']}; servos {models}")  # fmt: skip

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
        self._next_due_s = self._now()

    def _spin_up(self) -> None:
        s = self.settings
        self.omega_cmd = self.spins.copy()
        self.wheels.set_speeds(list(self.omega_cmd))
        deadline = self._now() + s.spinup_timeout_s
        steady_since = None
        while True:
            self._tick()
            tel = self.wheel_reader.latest
            err = np.max(np.abs(np.array(tel.omega_rad_s) - self.omega_cmd)) if tel else math.inf
            now = self._now()
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
        est_cfg = config_from_dict(noise_from_rig(self.config))
        model = self.model
        # as gyrotens replay starts: the scene's state, the last wheel speeds and string lengths
        x0 = from_model_state(model, model.initial_state(), model.input_at(0.0))
        layout = layout_of(model)
        x0[layout.omega] = np.array(self.wheel_reader.latest.omega_rad_s)[: layout.n_wheels]
        for string, state in zip(self.servo_strings, self.latest_servos, strict=False):
            x0[layout.rest.start + self.strings.index(string)] = state.length_m  # none yet: scene
        innovations = InnovationWriter(self.log, self.servo_strings)
        t0 = self._now()
        self.ekf = TensegrityEKF(model, est_cfg, x0=x0, t0_s=t0, log=innovations)
        self.log.update_meta(estimator=asdict(est_cfg))  # what gyrotens replay reads
        self.ekf.set_input(self.rest_cmd)
        self.estimates = EstimateWriter(self.log, self.ekf, self.tilt)
        self.estimate = ekf_estimate(self.ekf)

    # --- one tick -----------------------------------------------------------------------------
    def _now(self) -> float:
        return (time.monotonic_ns() - self._t0_ns) * 1e-9

    def _ticks(self, duration_s: float) -> None:
        end = self._now() + duration_s
        while self._now() < end:
            self._tick()

    def _tick(self, strict: bool = True) -> None:
        """Wait for the next tick of the grid, then drain, fuse, command, check and log.

        ``strict`` False (in the safe state): device faults are logged, not raised, no limit is
        checked and no hook called.
        """
        period = self.timer.period_s
        due = self._next_due_s
        wait = due - self._now()
        if wait > 0:
            time.sleep(wait)
        start, cpu0 = self._now(), time.thread_time()
        self.timer.record(start, due)
        self._next_due_s = due + period * max(1, math.ceil((start - due) / period))
        n = self._drain(strict)
        self._command(start)
        if self.ekf is not None:
            self.ekf.advance(max(start, self.ekf.t))
            _, self.latest_tilt = self.estimates.write(start)
            if strict and self.phase == "schedule" and self.maneuver is not None:
                self._follow_estimate()
        if self.truth is not None:
            self._write_truth(strict)
        if strict:
            self._check_limits()
        cpu = time.thread_time() - cpu0
        self.loop_stream.write(start, start - due, self._now() - start, cpu, n, self.phase)
        if self.progress is not None:
            self.progress(self.phase, start, self._played(start))
        if strict and self.on_tick is not None:
            self.on_tick(self, self.phase, start)

    def _follow_estimate(self) -> None:
        """Closed loop: the estimate to the maneuver, its schedule from the next tick on."""
        t_s, x = self.estimate()
        self.schedule = self.maneuver.update(t_s - self.t_schedule_s, x)
        self.replans.write(self.maneuver.records)

    def _write_truth(self, strict: bool) -> None:
        try:
            self.truth.write()
        except RigProcessError as exc:
            if strict:
                raise
            self.event("fault", str(exc))
            self.truth = None

    def _played(self, t_s: float) -> float:
        if self.phase in ("settle", "rampdown"):
            return 1.0
        if self.phase != "schedule":
            return 0.0
        return min((t_s - self.t_schedule_s) / max(self.schedule.t_end, 1e-9), 1.0)

    def _drain(self, strict: bool) -> int:
        items = []
        while True:
            try:
                items.append(self.queue.get_nowait())
            except queue.Empty:
                break
        faults = [i for i in items if isinstance(i, BaseException)]
        samples = sorted((i for i in items if isinstance(i, Sample)), key=lambda s: s.t_ns)
        for sample in samples:
            self._take(sample, self._fusable(sample, samples))
        for fault in faults:
            if strict:
                raise fault
            self.event("fault", str(fault))
        return len(samples)

    def _fusable(self, sample: Sample, samples: list) -> bool:
        """Fuse only a device's newest ``max_fused_per_tick`` samples of a tick (all are logged):
        a loop that fell behind catches up instead of spiralling."""
        if self.ekf is None or (sample.t_ns - self._t0_ns) * 1e-9 < self.ekf.t_start:
            return False
        newer = sum(1 for s in samples if s.device == sample.device and s.t_ns > sample.t_ns)
        if newer < self.settings.max_fused_per_tick:
            return True
        self.skipped[sample.device] = self.skipped.get(sample.device, 0) + 1
        return False

    def _take(self, sample: Sample, fuse: bool) -> None:
        t = (sample.t_ns - self._t0_ns) * 1e-9
        v = sample.value
        if sample.device == "imu":
            self.imu_stream.write(
                t, *v.omega_rad_s, *v.accel_m_s2, *v.euler_rad, v.temperature_degC
            )
            if fuse:
                self.ekf.fuse_imu(t, v.omega_rad_s, v.accel_m_s2, v.euler_rad)
        elif sample.device == "wheels":
            self.wheel_stream.write(t, *v.omega_rad_s, v.t_us, v.seq, v.status, v.faults, *v.drive)
            if fuse:
                self.ekf.fuse_wheels(t, np.array(v.omega_rad_s)[: len(self.model.wheel_bars)])
        else:
            self.servo_stream.write(
                t,
                *(s.length_m for s in v),
                *(s.speed_m_s for s in v),
                *(s.load_fraction for s in v),
            )
            self.latest_servos = v
            if fuse:
                idx = [self.strings.index(name) for name in self.servo_strings]
                self.ekf.fuse_servos(t, [s.length_m for s in v], idx)

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
            if self.ekf is not None:
                self.ekf.set_input(rest)
        self.command_stream.write(t_s, *self.rest_cmd, *self.omega_cmd)

    def _check_limits(self) -> None:
        s = self.settings
        tel = self.wheel_reader.latest if self.wheels is not None else None
        if tel is not None:
            limit = np.max(np.abs(self.omega_cmd)) + s.wheel_speed_margin_rad_s
            fast = np.max(np.abs(tel.omega_rad_s))
            if fast > limit:
                raise LimitBreach(f"wheel speed {fast:.2f} rad/s above the limit {limit:.2f} rad/s")
        for state in self.latest_servos:
            if abs(state.load_fraction) > s.max_servo_load:
                raise LimitBreach(
                    f"servo '{state.name}' load {state.load_fraction:.2f} above the limit "
                    f"{s.max_servo_load:g}"
                )
        if abs(self.latest_tilt) > s.max_tilt_rad:
            raise LimitBreach(
                f"estimated tilt {self.latest_tilt:.3f} rad beyond the limit {s.max_tilt_rad:g} rad"
            )
        if self.ekf is not None and self.ekf.status & Status.PREDICTION_ONLY:
            raise RunError(f"estimator fault: every source timed out (status {self.ekf.status!r})")

    # --- the safe state -----------------------------------------------------------------------
    def safe_state(self, reason: str) -> dict:
        """Ramp the wheels down, hold the servos, log the outcome; returns what was reached.

        Ctrl-C is ignored meanwhile (when running in the main thread): the routine is bounded
        by ``rampdown_timeout_s`` plus the servo reply time-outs.
        """
        with _SigintDeferred(self):
            self.phase = "rampdown"
            self.event("safe_state", f"reason: {reason}")
            self.ekf = None  # the estimate ends with the run; the safe state needs none
            self._next_due_s = max(self._next_due_s, self._now())
            self.omega_cmd = np.zeros(wp.N_WHEELS)
            out = {"reason": reason, "wheels_stopped": None, "servos_holding": False}
            out.update(self._stop_wheels())
            out.update(self._hold_servos())
            for r in self.readers:
                if r is not self.servo_worker:
                    r.stop()
            self.event("safe_state", _describe_safe(out))
            self._close_devices()
        return out

    def _stop_wheels(self) -> dict:
        if self.wheels is None or self.wheels.hello is None:
            return {}  # never connected: the board's own fail-safe holds its wheels
        s = self.settings
        try:
            self.wheels.stop_all()
        except WheelBoardError as exc:
            self.event("fault", f"stop_all failed ({exc}); the board's heartbeat fail-safe stops")
        start = self._now()
        fastest, stopped = math.inf, False
        while not stopped and self._now() - start < s.rampdown_timeout_s:
            self._tick(strict=False)
            tel = self.wheel_reader.latest
            if tel is None:
                continue
            fastest = float(np.max(np.abs(tel.omega_rad_s)))
            # setpoints at zero and drive stages off (the rest is coasting), or slow already
            stopped = "OUTPUTS_ENABLED" not in tel.status_names or fastest < s.stop_threshold_rad_s
        return {"wheels_stopped": stopped, "wheel_speed_max_rad_s": fastest,
                "rampdown_s": self._now() - start}  # fmt: skip

    def _hold_servos(self) -> dict:
        if self.servos is None:
            return {}
        if self.servo_worker is not None:
            self.servo_worker.stop()
        try:
            states = self.servos.hold()
        except Exception as exc:  # report and go on: the wheels are what must stop
            self.event("fault", f"servo hold failed: {type(exc).__name__}: {exc}")
            return {"servos_holding": False}
        held = {s.name: s.length_m for s in states}
        faults = {s.name: list(s.faults) for s in states if s.faults}
        return {"servos_holding": True, "servo_lengths_m": held, "servo_faults": faults}

    def _close_devices(self) -> None:
        for dev in (self.wheels, self.servos, self.imu):  # pyserial errors are OSErrors
            if dev is not None:
                try:
                    dev.close()
                except (OSError, WheelBoardError) as exc:
                    self.event("fault", f"closing {type(dev).__name__}: {exc}")

    # --- the log ------------------------------------------------------------------------------
    def _meta(self) -> dict:
        return {
            "software": {"gyrotens": __version__},
            "rig_config": asdict(self.config),
            "scene": str(self.config.scene_path),
            "schedule": self.schedule.to_dict(),
            **({"target": self.maneuver.target.to_dict()} if self.maneuver else {}),
            "settings": asdict(self.settings),
            "time": "t_s: host time since the start of the run (time.monotonic), s",
            **self._extra_meta,
        }

    def _open_streams(self) -> None:
        log = self.log
        self._t0_ns = time.monotonic_ns()
        self.events = log.stream(
            "events", ["t_s", "kind", "message"], ("kind", "message"), "phases, faults, outcome"
        )
        self.loop_stream = log.stream(
            "loop",
            ["t_s", "late_s", "work_s", "cpu_s", "samples", "phase"],
            ("phase",),
            "one row per host tick: lateness against the grid, wall and CPU time spent (s)",
        )
        self.imu_stream = log.stream(
            cols.IMU, [*cols.imu_columns(), "temperature_degC"], (), "IMU samples at arrival"
        )
        self.wheel_stream = log.stream(
            cols.WHEELS,
            [
                *cols.wheels_columns(),
                "device_t_us",
                "seq",
                "status",
                "faults",
                *(f"drive_{i}" for i in range(wp.N_WHEELS)),
            ],
            description="wheel-board telemetry at arrival; drive as a fraction of the supply",
        )
        names = self.servo_strings
        self.servo_stream = log.stream(
            cols.SERVOS,
            [
                *cols.servos_columns(names),
                *(f"{n}_speed_m_s" for n in names),
                *(f"{n}_load" for n in names),
            ],
            description="servo read-back at arrival; load as a fraction of the maximum torque",
        )
        self.command_stream = log.stream(
            cols.COMMAND,
            cols.command_columns(self.strings),
            description="commanded rest lengths (m) and wheel speeds (rad/s), every tick",
        )
        if self.rig is not None:
            self.truth = TruthProbe(self.rig, log, self.tilt, self._t0_ns)
        if self.maneuver is not None:
            self.replans = ReplanWriter(log, lambda: self.t_schedule_s)
            self.replans.write(self.maneuver.records)  # the first plan, made before the run

    def event(self, kind: str, message: str) -> None:
        """Append one row to the ``events`` stream (commas become semicolons)."""
        text = " ".join(str(message).replace(",", ";").split())
        self.events.write(self._now(), kind, text)

    def _summary(self, reason: str, safe: dict) -> dict:
        timing = self.timer.stats()
        out = {
            "reason": reason,
            "completed": reason == "completed",
            "safe_state": safe,
            "loop": timing,
            "rows": {name: s.rows for name, s in self.log.streams.items()},
            "not_fused": self.skipped,
            "servo_comm_retries": getattr(self.servo_worker, "comm_errors_total", 0),
            "duration_s": self._now(),
        }
        out.update(self.final)
        if self.maneuver is not None:
            out["maneuver"] = self.maneuver.summary()
            target = self.maneuver.target.tilt_rad
            for key in ("tilt_end", "tilt_settled"):
                if f"{key}_truth_rad" in out:
                    out[f"{key}_truth_error_rad"] = out[f"{key}_truth_rad"] - target
        if self.rig is not None:
            try:
                out["rig"] = self.rig.stats_lines()
            except RigProcessError as exc:
                out["rig"] = [str(exc)]
        self.event("timing", jitter_line(timing))
        return out


def _describe_safe(out: dict) -> str:
    wheels = out.get("wheels_stopped")
    if wheels is None:
        w = "wheels never started"
    else:
        w = (
            f"wheels {'ramped down' if wheels else 'NOT ramped down'} (max "
            f"{out['wheel_speed_max_rad_s']:.2f} rad/s after {out['rampdown_s']:.2f} s)"
        )
    return f"{w}; servos {'holding' if out['servos_holding'] else 'NOT holding'}"


class _SigintDeferred:
    """Context: Ctrl-C prints a note instead of interrupting (main thread only)."""

    def __init__(self, loop: RunLoop):
        self.loop = loop
        self.previous = None

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self.previous = signal.signal(signal.SIGINT, self._note)
        return self

    def _note(self, *_):
        self.loop.event("interrupt", "Ctrl-C during the safe state: ignored until it is reached")

    def __exit__(self, *exc):
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)
        return False


def run_simulated(
    config, schedule: Schedule | Maneuver, log_folder, scene=None, **kwargs
) -> RunResult:
    """Start the simulated rig in a child process (real-time clock) and run on its ptys.

    Parameters
    ----------
    config : RigConfig
        Ports are replaced by the rig's pseudo-terminals; ``sim`` tables configure the rig.
    schedule : Schedule or Maneuver
    log_folder : path
    scene : path, optional
        Scene of the rig and of the estimator (default: the configuration's).
    **kwargs
        Passed on to :class:`RunLoop` (``settings``, ``on_tick``, ``progress``, ``meta``).
    """
    if scene is not None:
        config = replace(config, scene=str(Path(scene).resolve()))
    check_schedule(getattr(schedule, "schedule", schedule), config.servos.servo)
    rate_hz = (kwargs.get("settings") or RunSettings()).rate_hz
    with RigProcess(config, period_s=1.0 / rate_hz) as rig:
        return RunLoop(with_ports(config, rig.paths), schedule, log_folder, rig=rig, **kwargs).run()


def with_ports(config, ports: dict):
    """``config`` with device ports replaced: ``ports`` maps ``imu``, ``wheels``, ``servos`` to a
    path (a missing or ``None`` entry keeps the configured port)."""
    return replace(
        config,
        imu=replace(config.imu, port=ports.get("imu") or config.imu.port),
        wheelboard=replace(config.wheelboard, port=ports.get("wheels") or config.wheelboard.port),
        servos=replace(config.servos, port=ports.get("servos") or config.servos.port),
    )
