"""The simulated rig: truth model and the three device emulators, served by one thread.

One loop thread owns everything: it steps the truth (:class:`~gyrohost.simrig.truth.Truth`) with
the emulated servos' string lengths and the emulated wheel board's true speeds, hands the string
tensions back to the servos, polls the three emulators (input, ticks, output) and applies timed
faults. The drivers open :attr:`SimulatedRig.paths` exactly as they open hardware.

Clocks:

- ``"real"``: rig time is wall time since :meth:`SimulatedRig.start`; the truth steps when due.
  A step that starts more than one step period after its due time counts as late. The devices
  always run on wall time, so their rates hold on a loaded CPU; the truth then lags (the IMU
  waits for it ``imu_emu.TRUTH_WAIT_S`` at most), by at most ``MAX_LAG_S``: beyond that it slips,
  i.e. runs slower than wall time. Lateness and slip are reported (:class:`RigStats`).
- ``"sim"``: rig time stands still until :meth:`SimulatedRig.advance` moves it; the loop then
  steps and ticks through the interval as fast as it can and returns. In between, the loop still
  answers the drivers (at the frozen time), so request/reply traffic works. Because the host's
  wheel-board heartbeat runs on wall time, advance in chunks shorter than HEARTBEAT_MS while the
  wheel-board client is connected (or raise HEARTBEAT_MS).

Run-time faults: :meth:`SimulatedRig.inject`, or :meth:`SimulatedRig.command` with the text
form (``"fault imu silence 2"``) used by ``gyrotens rig`` on its standard input, and ``reset``
(:meth:`SimulatedRig.reset`, between two runs against one rig); see docs/rig.md.
"""

import select
import threading
import time
from collections import deque
from pathlib import Path

import numpy as np

from gyrohost.config import RigConfig
from gyrohost.simrig import simavr
from gyrohost.simrig.config import WHEEL_KINDS, sim_config
from gyrohost.simrig.imu_emu import Bwt61Emulator
from gyrohost.simrig.servo_emu import Mx12Bus
from gyrohost.simrig.stats import RigStats
from gyrohost.simrig.truth import Truth, TruthRecord, truth_scene
from gyrohost.simrig.wheel_emu import WheelBoardEmulator

from .errors import FaultCommandError, HarnessError, RigError, RigSetupError

DEVICES = ("imu", "wheels", "servos")
IDLE_WAIT_S = 0.001
"""Longest wait for driver input between two polls of the emulators, s."""
MAX_LAG_S = 0.25
"""Real clock: the truth lags wall time by at most this much; beyond, it slips (runs slower)."""

STEPS_KEPT = 400
"""Truth steps :meth:`SimulatedRig.truth_steps` keeps for its reader: 2 s of 5 ms steps, some
hundred times the period it is read at."""
STREAM_FAULTS = ("corrupt", "drop", "silence", "stall", "clear")
DEVICE_FAULTS = {"wheels": ("reset", "watchdog"), "servos": ("overload", "timeout")}


class SimulatedRig:
    """Truth model plus IMU, wheel-board and servo emulators on pseudo-terminals.

    Parameters
    ----------
    config : RigConfig
        Servos (IDs, calibration, ``string``), IMU rate and mounting, ``sim`` tables.
    clock : {"real", "sim"}
        Rig time source (see the module docstring).
    scene : str or Path, optional
        Scene file; the configuration's ``scene`` when omitted. The truth runs
        ``[sim.truth] scene`` instead when the configuration sets one (checked against this).
    wheels : {"emulator", "simavr"}, optional
        Wheel board: the Python emulator, or the real firmware in the simavr harness (its own
        pty, paced to wall time; :mod:`gyrohost.simrig.simavr`). The configuration's
        ``[sim.wheels] kind`` when omitted.

    Examples
    --------
    >>> with SimulatedRig(config, clock="sim") as rig:
    ...     imu = Bwt61Driver(rig.paths["imu"]).open()
    ...     rig.advance(0.5)
    ...     N = rig.truth_nodes()
    """

    def __init__(
        self,
        config: RigConfig,
        clock: str = "real",
        scene: str | Path | None = None,
        wheels: str | None = None,
    ):
        if clock not in ("real", "sim"):
            raise ValueError(f"clock must be 'real' or 'sim', got {clock!r}")
        self.sim = sim = sim_config(config)
        self.wheels_kind = wheels or sim.wheels.kind
        if self.wheels_kind not in WHEEL_KINDS:
            raise ValueError(f"wheels must be one of {WHEEL_KINDS}, got {wheels!r}")
        self.config = config
        self.clock = clock
        self.truth = Truth(truth_scene(config, scene), sim.truth, config.servos.servo)
        self.imu = Bwt61Emulator(
            sim.imu,
            config.imu,
            truth_source=self._imu_truth,
            rotation_deg=sim.truth.imu_rotation_deg,
            truth_ready=self._has_imu_truth,
        )
        self.servos = Mx12Bus(config.servos.servo, sim.servos)
        self.wheels = self._wheel_board(config)
        self._spin_sign = np.asarray(sim.wheels.spin_sign, dtype=float)
        self.devices = {"imu": self.imu, "wheels": self.wheels, "servos": self.servos}
        self.loop_error: BaseException | None = None
        self._lock = threading.RLock()
        self._cond = threading.Condition()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._timers: list[tuple[float, object]] = []
        self._t0_wall = 0.0
        self._sim_target_s = 0.0
        self._idle_at_s = -1.0
        self._dev_t_s = 0.0
        self._steps = self._late = 0
        self._step_wall_s = self._max_lag_s = self._slip_s = 0.0
        self._cpu0_s = 0.0
        self._steps_kept: deque | None = None  # kept once asked (keep_truth_steps)

    def _wheel_board(self, config: RigConfig):
        emu = self.sim.wheels
        if self.wheels_kind == "emulator":
            return WheelBoardEmulator(emu, config.wheelboard.baud)
        try:
            return simavr.simavr_wheel_board(
                emu.simavr_elf, emu.simavr_harness, emu.simavr_options, config.base_dir
            )
        except HarnessError as exc:
            self.imu.close()
            self.servos.close()
            raise RigSetupError(f"wheels = simavr: {exc}") from exc

    # --- life cycle ---------------------------------------------------------------------------
    @property
    def paths(self) -> dict[str, str]:
        """Device name (``imu``, ``wheels``, ``servos``) -> pty path to open as the port."""
        return {name: dev.slave_path for name, dev in self.devices.items()}

    def start(self) -> "SimulatedRig":
        """Start the loop thread (idempotent); returns ``self``."""
        if self._thread is None:
            self._t0_wall = time.monotonic()
            if self.clock == "real":  # a sim clock's bytes arrive at its polls, reproducibly
                self.servos.stamp_arrivals(self._t0_wall)
            self._cpu0_s = time.process_time()
            self._thread = threading.Thread(target=self._run, name="rig", daemon=True)
            self._thread.start()
        return self

    def close(self) -> None:
        """Stop the loop and close the three pseudo-terminals (idempotent)."""
        self._stop.set()
        with self._cond:
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        for dev in self.devices.values():
            dev.close()

    def __enter__(self) -> "SimulatedRig":
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def check(self) -> None:
        """Raise :class:`RigError` if the loop thread has failed."""
        if self.loop_error is not None:
            raise RigError(f"the rig loop stopped: {self.loop_error!r}") from self.loop_error

    # --- time ---------------------------------------------------------------------------------
    @property
    def t_s(self) -> float:
        """Rig (device) time, s."""
        return self._dev_t_s

    @property
    def slip_s(self) -> float:
        """How far the truth's clock has fallen behind the rig's for good (a loaded CPU), s."""
        return self._slip_s

    def advance(self, dt_s: float, timeout_s: float = 600.0) -> None:
        """Move simulated time on by ``dt_s`` s and return when the rig has caught up.

        Raises
        ------
        RigError
            Not a ``"sim"`` clock, the rig is not started, or its loop failed.
        """
        if self.clock != "sim":
            raise RigError("advance() needs clock='sim'; a real-clock rig follows wall time")
        if self._thread is None:
            raise RigError("advance(): start the rig first (use it as a context manager)")
        if not dt_s >= 0:
            raise ValueError(f"advance(): dt_s must be >= 0, got {dt_s}")
        deadline = time.monotonic() + timeout_s
        with self._cond:
            self._sim_target_s += dt_s
            target = self._sim_target_s
            self._cond.notify_all()
            while self._idle_at_s < target and self.loop_error is None:
                if not self._cond.wait(timeout=max(deadline - time.monotonic(), 0.0)):
                    raise RigError(f"advance(): rig time did not reach {target:.3f} s in time")
        self.check()

    def _target_s(self) -> float:
        if self.clock == "real":
            return time.monotonic() - self._t0_wall
        return self._sim_target_s

    def _truth_target_s(self, now_s: float) -> float:
        """Time the truth should reach at rig time ``now_s``: less the slip (real clock)."""
        target = now_s - self._slip_s
        behind = target - self.truth.t_s - self.truth.dt_s
        if self.clock == "real" and behind > MAX_LAG_S:
            self._slip_s += behind - MAX_LAG_S
            target -= behind - MAX_LAG_S
        return target

    # --- the loop -----------------------------------------------------------------------------
    def _run(self) -> None:
        inputs = [dev.waitable() for dev in self.devices.values() if dev.link is not None]
        try:
            while not self._stop.is_set():
                now = self._target_s()
                target = self._truth_target_s(now)
                due = self.truth.t_s + self.truth.dt_s
                if due <= target + 1e-9:
                    # the devices' outputs at the step's end (_step_inputs); a device that takes
                    # bytes at the poll's time runs to the present (PtyDevice.poll)
                    self._poll(due, now if self.clock == "real" else None)
                    self._step(target - due)
                    # Devices keep wall time even while a loaded CPU makes the truth lag.
                    self._poll(self._target_s() if self.clock == "real" else self.truth.t_s)
                    continue
                self._poll(now)
                if self.clock == "sim":
                    with self._cond:
                        self._idle_at_s = now
                        self._cond.notify_all()
                wait = self._wait_s(now, due - target)
                select.select(inputs, [], [], wait)
        except BaseException as exc:  # reported by check()/advance(); the thread must not vanish
            self.loop_error = exc
            with self._cond:
                self._cond.notify_all()

    def _wait_s(self, now_s: float, step_due_s: float) -> float:
        """How long the loop may wait for driver input, s: to the truth's next step or a
        device's next sample on a real clock (the IMU's, the wheel board's telemetry: a sample
        reaches the host when its bits have crossed the wire, not up to a poll later), at most
        :data:`IDLE_WAIT_S`. An IMU sample past its time waits for the truth, which the step
        brings."""
        if self.clock != "real":
            return IDLE_WAIT_S
        waits = [step_due_s, IDLE_WAIT_S]
        for dev in self.devices.values():
            send_s = dev.next_send_s
            if send_s is not None and send_s > now_s:
                waits.append(send_s - now_s)
        return max(min(waits), 0.0)

    def _step(self, lateness_s: float) -> None:
        start = time.perf_counter()
        with self._lock:
            self.truth.step(*self._step_inputs())
            for sid, tension in self.truth.servo_tensions_N().items():
                self.servos.set_tension(sid, tension)
            if self._steps_kept is not None:
                self._steps_kept.append((time.monotonic_ns(), self._dev_t_s, *self._sample()))
        self._step_wall_s += time.perf_counter() - start
        self._steps += 1
        if self.clock == "real":
            self._max_lag_s = max(self._max_lag_s, lateness_s)
            self._late += lateness_s > self.truth.dt_s

    def _step_inputs(self) -> tuple[dict, np.ndarray, list]:
        """The servos' string lengths (servo ID -> m) and the wheels' speeds (rad/s) at the
        end of the step now due, where the devices have been polled, and the servos' turns
        within it: (truth time, lengths) where a servo's path bends (:class:`~gyrohost.simrig.
        servo_emu.ServoPath`). The truth moves its inputs there from the last step's
        (:meth:`Truth.step`)."""
        start = self.truth.t_s + self._slip_s  # on the devices' clock
        end = start + self.truth.dt_s
        turns = [
            (t - self._slip_s, self._lengths_at(t)) for t in self.servos.turns_between(start, end)
        ]
        wheels = np.asarray(self.wheels.wheel_speeds_rad_s(at_s=end)) * self._spin_sign
        return self._lengths_at(end), wheels, turns

    def _lengths_at(self, t_s: float) -> dict:
        """The servos' string lengths (servo ID -> m) at device time ``t_s``."""
        lengths = self.servos.lengths_at(t_s)
        return {sid: lengths[sid] for sid in self.truth.servo_strings}

    def _poll(self, t_s: float, present_s: float | None = None) -> None:
        self._dev_t_s = t_s = max(t_s, self._dev_t_s)
        with self._lock:
            due = [action for when, action in self._timers if when <= t_s]
            self._timers = [(w, a) for w, a in self._timers if w > t_s]
            for action in due:
                action()
            for dev in self.devices.values():
                dev.poll(now_s=t_s, timeout_s=0.0, present_s=present_s)

    # --- truth read-outs ----------------------------------------------------------------------
    def _imu_truth(self, rig_t_s: float):
        """The IMU's truth at rig time ``rig_t_s`` (on the truth's clock: less the slip)."""
        return self.truth.imu_truth(rig_t_s - self._slip_s)

    def _has_imu_truth(self, rig_t_s: float) -> bool:
        return self.truth.has_imu_truth(rig_t_s - self._slip_s)

    def truth_nodes(self) -> np.ndarray:
        """True scene node positions now, shape (3, n), m."""
        with self._lock:
            return self.truth.nodes()

    def truth_wheel_speeds(self) -> np.ndarray:
        """True wheel spins now, shape (n_w,), rad/s (scene wheel order)."""
        with self._lock:
            return self.truth.wheel_speeds_rad_s()

    def truth_rest_lengths(self) -> np.ndarray:
        """True string rest lengths now, shape (alpha,), m."""
        with self._lock:
            return self.truth.rest_length_m.copy()

    def truth_sample(self) -> tuple[float, float, np.ndarray, np.ndarray, np.ndarray]:
        """The truth read at one instant: its time, s, the rig time its state belongs to
        (time plus slip), s, node positions (3, n), m, wheel spins (n_w,), rad/s, and rest
        lengths (alpha,), m. One lock for all: the loop thread steps the truth between
        separate reads, and a state a few steps past its stamp is a large error while the
        D-bar turns fast."""
        with self._lock:
            return self._sample()

    def keep_truth_steps(self) -> None:
        """Keep every following truth step's sample for :meth:`truth_steps` (a rig whose truth
        nobody streams leaves the nodes of each step uncomputed)."""
        with self._lock:
            if self._steps_kept is None:
                self._steps_kept = deque(maxlen=STEPS_KEPT)

    def truth_steps(self) -> list[tuple]:
        """Every truth step's sample since the last call (at most :data:`STEPS_KEPT`; none
        before :meth:`keep_truth_steps`), oldest first: ``time.monotonic_ns`` and the rig time
        when it was stepped, then :meth:`truth_sample`'s values.

        The truth holds its inputs first-order between its steps' ends: a reader that
        interpolates between every step's sample has what the physics had, where one sampling
        the latest step now and then interpolates over steps it missed: sampled once per tick,
        a rest length moving a goal step a tick is off by up to that step between samples, by
        an offset the ticks' phase against the steps holds for a whole run."""
        with self._lock:
            out = list(self._steps_kept or ())
            if self._steps_kept is not None:
                self._steps_kept.clear()
        return out

    def _sample(self) -> tuple:
        t_s = self.truth.t_s
        return (
            t_s,
            t_s + self._slip_s,
            self.truth.nodes(),
            self.truth.wheel_speeds_rad_s(),
            self.truth.rest_length_m.copy(),
        )

    def start_recording(self) -> None:
        """Record the truth at every following step (see :meth:`recording`)."""
        with self._lock:
            self.truth.start_recording()

    def recording(self) -> TruthRecord:
        """Truth recorded since :meth:`start_recording` (a snapshot)."""
        with self._lock:
            return self.truth.recording()

    def stats(self) -> RigStats:
        """Counts and timing so far."""
        elapsed = time.monotonic() - self._t0_wall if self.clock == "real" else self._dev_t_s
        return RigStats(
            elapsed_s=elapsed,
            imu_samples=self.imu.samples_sent,
            telemetry_frames=self.wheels.telemetry_sent,
            servo_packets=self.servos.packets_seen,
            truth_steps=self._steps,
            late_steps=self._late,
            truth_dt_s=self.truth.dt_s,
            step_wall_s=self._step_wall_s,
            max_lag_s=self._max_lag_s,
            slipped_s=self._slip_s,
            cpu_s=time.process_time() - self._cpu0_s,
        )

    # --- faults -------------------------------------------------------------------------------
    def inject(
        self,
        device: str,
        fault: str,
        count: int = 1,
        duration_s: float | None = None,
        servo_id: int | None = None,
    ) -> None:
        """Inject a fault now.

        Parameters
        ----------
        device : {"imu", "wheels", "servos"}
        fault : str
            Any device: ``corrupt`` / ``drop`` (the next ``count`` bytes it sends), ``silence``
            (nothing sent, for ``duration_s`` or until ``clear``), ``stall`` (bytes held for
            ``duration_s``, then one burst), ``clear`` (end a silence, overload or timeout).
            ``wheels``: ``reset`` / ``watchdog`` (reboot after ``duration_s`` down, default 0).
            ``servos``: ``overload`` / ``timeout`` of ``servo_id`` (for ``duration_s`` or until
            ``clear``).
        count : int
        duration_s : float, optional, s
        servo_id : int, optional

        Raises
        ------
        FaultCommandError
            Unknown device or fault, or a missing argument.
        """
        if device not in self.devices:
            raise FaultCommandError(f"unknown device {device!r} (one of {', '.join(DEVICES)})")
        if device == "wheels" and self.wheels_kind == "simavr":
            raise FaultCommandError(
                "wheel-board faults need the emulator: with simavr wheels the host opens the "
                "harness's pty directly (its encoder faults: see docs/fil.md)"
            )
        known = STREAM_FAULTS + DEVICE_FAULTS.get(device, ())
        if fault not in known:
            raise FaultCommandError(f"unknown {device} fault {fault!r} (one of {', '.join(known)})")
        with self._lock:
            self._apply(device, fault, count, duration_s, servo_id)

    def _apply(self, device, fault, count, duration_s, servo_id) -> None:
        dev, now = self.devices[device], self._dev_t_s
        if fault == "corrupt":
            dev.faults.corrupt_next(count)
        elif fault == "drop":
            dev.faults.drop_next(count)
        elif fault == "stall":
            dev.faults.stall_for(_required(duration_s, fault), now)
        elif fault == "silence":
            dev.faults.set_silent(True)
            self._later(duration_s, lambda: dev.faults.set_silent(False))
        elif fault in ("reset", "watchdog"):
            self.wheels.reset(down_s=duration_s or 0.0, watchdog=fault == "watchdog")
        elif fault in ("overload", "timeout"):
            if servo_id not in self.servos.servos:
                raise FaultCommandError(
                    f"servos {fault}: servo ID {servo_id} is not on the bus "
                    f"(IDs {sorted(self.servos.servos)})"
                )
            setter = self.servos.set_overload if fault == "overload" else self.servos.set_no_reply
            setter(servo_id, True)
            self._later(duration_s, lambda: setter(servo_id, False))
        else:  # clear
            dev.faults.set_silent(False)
            if device == "servos":
                for sid in self.servos.servos:
                    self.servos.set_overload(sid, False)
                    self.servos.set_no_reply(sid, False)

    def reset(self) -> str:
        """The truth to the scene's initial state, the servos to their start, the emulated wheels
        to rest (simavr wheels run as the firmware drives them); returns what was done."""
        with self._lock:
            self.truth.reset()
            self.servos.reset()
            if self.wheels_kind == "emulator":
                self.wheels.rest()
        wheels = "wheels at rest" if self.wheels_kind == "emulator" else "simavr wheels as they are"
        return f"reset: truth at the scene's initial state, servos at their start, {wheels}"

    def _later(self, duration_s: float | None, action) -> None:
        if duration_s is not None:
            self._timers.append((self._dev_t_s + duration_s, action))

    def command(self, line: str) -> str:
        """Run one text command; returns a one-line answer.

        ``fault DEVICE FAULT [ARG...]`` (``fault imu silence 2``, ``fault wheels corrupt 40``,
        ``fault servos overload 1 0.5``, ``fault wheels reset``), ``stats``, ``reset`` or
        ``release`` (a held truth's structure let go, :meth:`Truth.release`).

        Raises
        ------
        FaultCommandError
            The line is not a command the rig knows.
        """
        words = line.split()
        if words == ["stats"]:
            stats = self.stats()
            return f"{stats.rates_line()}; {stats.truth_line()}"
        if words == ["reset"]:
            return self.reset()
        if words == ["release"]:
            with self._lock:
                held = self.truth.release()
            return "release: the structure is free" if held else "release: nothing was held"
        if len(words) < 3 or words[0] != "fault":
            raise FaultCommandError(f"unknown command {line.strip()!r}: try 'fault imu silence 2'")
        device, fault, args = words[1], words[2], words[3:]
        try:
            numbers = [float(a) for a in args]
        except ValueError:
            raise FaultCommandError(f"{line.strip()!r}: arguments must be numbers") from None
        kwargs: dict = {}
        if fault in ("corrupt", "drop"):
            kwargs["count"] = int(numbers[0]) if numbers else 1
        elif fault in ("overload", "timeout"):
            if not numbers:
                raise FaultCommandError(f"{line.strip()!r}: give the servo ID")
            kwargs["servo_id"] = int(numbers[0])
            kwargs["duration_s"] = numbers[1] if len(numbers) > 1 else None
        elif numbers:
            kwargs["duration_s"] = numbers[0]
        self.inject(device, fault, **kwargs)
        return f"injected: {device} {fault} {' '.join(args)}".rstrip()


def _required(duration_s: float | None, fault: str) -> float:
    if duration_s is None:
        raise FaultCommandError(f"fault {fault!r} needs a duration, s")
    return duration_s
