"""Device I/O of the run loop in background threads, so the fixed-rate loop never waits on a port.

Each device gets one reader that turns what arrives into :class:`Sample` objects (host arrival
time plus the parsed values) on one shared queue; a reader that fails (whatever it raises) puts a
:class:`DeviceFault` there instead and stops, so the loop learns about it at its next tick.

- :class:`ImuReader`: polls the BWT61CL driver; silence longer than ``silence_s`` is a fault.
- :class:`WheelTelemetry`: the wheel-board client already reads in its own thread; this stamps
  every TELEMETRY on arrival, notices a board reboot (device time running backwards), latched
  faults and silence.
- :class:`ServoWorker`: owns the Dynamixel bus while the loop runs (the SDK is not thread-safe):
  sends the newest length goals as soon as the loop gives them (also while it waits for a
  reply), reads the states back at ``rate_hz``; a servo that does not answer is a fault at its
  first reply time-out.

Before any of them, :func:`check_real_rig` refuses a configuration of real ports that cannot
run: calibration keys left at the template's values, ports missing or not permitted.
"""

import queue
import threading
import time
from dataclasses import dataclass

from gyrohost.bringup.placeholders import find_placeholders
from gyrohost.bringup.serialports import check_ports
from gyrohost.config import ConfigError
from gyrohost.drivers.errors import ServoCommError, ServoTimeoutError

from .errors import DeviceFault

POLL_IDLE_S = 0.002
"""Sleep of the IMU reader when nothing has arrived, s (at most this much extra latency)."""


def failure_text(exc: BaseException) -> str:
    """``Type: message`` of an exception, its module named for a bare ``error``
    (``termios.error``)."""
    name = type(exc).__name__
    if name == "error":
        name = f"{type(exc).__module__}.error"
    return f"{name}: {exc}"


def device_ports(config) -> dict[str, str]:
    """Configuration key -> port of the three devices of ``config`` (a ``RigConfig``)."""
    return {
        "imu.port": config.imu.port,
        "wheelboard.port": config.wheelboard.port,
        "servos.port": config.servos.port,
    }


def check_real_rig(config) -> None:
    """Refuse a run on real ports before anything is opened (no log folder either).

    Raises
    ------
    ConfigError
        A calibration key of the configuration file is still at the lab-rig template's value
        (:mod:`gyrohost.bringup.placeholders`); every one is named.
    PortAccessError
        Ports missing or not readable and writable: one line per port, naming its key, with the
        fix for a permission (the ``dialout`` group).
    """
    if config.source.endswith(".toml"):
        unset = [p.describe() for p in find_placeholders(config.source) if p.required]
        if unset:
            raise ConfigError(
                f"{config.source}: calibration keys still at the template's values (calibrate "
                "them, docs/bring-up.md; 'gyrotens doctor' lists every check):\n  "
                + "\n  ".join(unset)
            )
    check_ports(device_ports(config), config.source)


@dataclass(frozen=True)
class Sample:
    """One device sample as it arrived.

    Attributes
    ----------
    device : str
        ``imu``, ``wheels``, ``servos`` or ``servo_goals`` (the goals the servo worker sent).
    t_ns : int
        Host arrival time (``time.monotonic_ns``), ns.
    value : object
        The driver's sample: ``ImuSample``, ``wheelproto.Telemetry`` or a list of ``ServoState``.
    """

    device: str
    t_ns: int
    value: object


class _Reader:
    """A daemon thread that calls ``self._cycle()`` until stopped; errors become faults."""

    name = "device"

    def __init__(self, out: queue.Queue):
        self.out = out
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"run-{self.name}", daemon=True)

    def start(self):
        self._thread.start()
        return self

    @property
    def alive(self) -> bool:
        """The thread is running."""
        return self._thread.is_alive()

    def stop(self, timeout_s: float = 2.0) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout_s)

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                self._cycle()
        except DeviceFault as exc:
            self.out.put(exc)
        except Exception as exc:  # a driver error, OSError, termios.error of a port gone: any
            self.out.put(DeviceFault(self.name, failure_text(exc)))

    def _cycle(self) -> None:  # pragma: no cover - every reader overrides it
        raise NotImplementedError


class ImuReader(_Reader):
    """Reads IMU samples; no sample for ``silence_s`` s is a :class:`DeviceFault`."""

    name = "imu"

    def __init__(self, driver, out: queue.Queue, silence_s: float):
        super().__init__(out)
        self.driver = driver
        self.silence_s = silence_s
        self._last_ns = time.monotonic_ns()
        self._stats_at_last = driver.stats.copy()

    def _cycle(self) -> None:
        samples = self.driver.poll()
        for s in samples:
            self.out.put(Sample("imu", s.t_ns, s))
        now = time.monotonic_ns()
        if samples:
            self._last_ns = now
            self._stats_at_last = self.driver.stats.copy()
            return
        if now - self._last_ns > self.silence_s * 1e9:
            seen = self.driver.stats.since(self._stats_at_last)
            raise DeviceFault("imu", f"no sample for {self.silence_s:g} s ({seen.describe()})")
        time.sleep(POLL_IDLE_S)


class WheelTelemetry(_Reader):
    """Stamps wheel-board telemetry on arrival and watches the board.

    Install :meth:`on_telemetry` as the client's ``on_telemetry`` callback. Faults (watched once
    :meth:`arm` is called, i.e. after faults latched before the run were cleared): telemetry
    silent for ``silence_s`` s, the device clock ``t_us`` running backwards (a reboot), and
    latched fault bits (names from the protocol table).

    Attributes
    ----------
    latest : wheelproto.Telemetry or None
        The newest frame; ``latest_ns`` its arrival time (``time.monotonic_ns``), ns.
    reboots : list of (int, str)
        Every reboot seen once armed (also after the first fault): arrival time, ns, and what
        the board reported (its clock, the reset cause).
    """

    name = "wheels"

    def __init__(self, out: queue.Queue, silence_s: float):
        super().__init__(out)
        self.silence_s = silence_s
        self.latest = None
        self.latest_ns: int | None = None
        self.reboots: list[tuple[int, str]] = []
        self._last_ns = time.monotonic_ns()
        self._last_t_us: int | None = None
        self._fault: DeviceFault | None = None
        self._armed = False

    def arm(self) -> None:
        """Start watching for faults (telemetry from now on)."""
        self._fault = None
        self._last_ns = time.monotonic_ns()
        self._armed = True

    def on_telemetry(self, tel) -> None:
        """Client callback (its reader thread): queue the sample, check for reboot and faults."""
        now = time.monotonic_ns()
        self._last_ns = now
        rebooted = self._last_t_us is not None and 0 < self._last_t_us - tel.t_us < 2**31
        if self._armed and rebooted:
            # the boot state (docs/protocol.md): drives off, no setpoint; the watchdog says so
            cause = "watchdog reset" if "WATCHDOG_RESET" in tel.fault_names else "reset"
            what = (
                f"board rebooted ({cause}: device clock went from {self._last_t_us} us to "
                f"{tel.t_us} us; drives off since, wheels coasting)"
            )
            self.reboots.append((now, what))
            self._fault = self._fault or DeviceFault("wheels", what)
        self._last_t_us = tel.t_us
        if self._armed and tel.faults:
            self._fault = self._fault or DeviceFault(
                "wheels", f"faults latched: {', '.join(tel.fault_names)}"
            )
        self.latest, self.latest_ns = tel, now
        self.out.put(Sample("wheels", now, tel))

    def _cycle(self) -> None:
        if self._fault is not None:
            raise self._fault
        if time.monotonic_ns() - self._last_ns > self.silence_s * 1e9:
            raise DeviceFault("wheels", f"no telemetry for {self.silence_s:g} s")
        self._stop.wait(0.01)


class ServoWorker(_Reader):
    """Owns the servo bus during the run: newest goals out, states in, at ``rate_hz``.

    A corrupt status packet is retried at the next cycle; ``max_comm_errors`` in a row make a
    fault. A servo silent for a whole reply time-out is a fault at once, naming it: a retry
    would only wait another time-out, with every servo's read-back missing meanwhile. While a
    reply is awaited, the loop's goals still go out (``PortHandler.while_waiting``), so the other
    servos follow the schedule until the loop ends the run. A fault bit in a status packet
    (overload, ...) is a fault at once.

    Parameters
    ----------
    bus : StringServoBus
    out : queue.Queue
    rate_hz : float, Hz
        Read-back rate; goals go out between reads, as they come.
    max_comm_errors : int
    """

    name = "servos"

    def __init__(self, bus, out: queue.Queue, rate_hz: float, max_comm_errors: int = 5):
        super().__init__(out)
        self.bus = bus
        self.period_s = 1.0 / rate_hz
        self.max_comm_errors = max_comm_errors
        self.comm_errors = 0
        self.comm_errors_total = 0
        self._goal_lock = threading.Lock()
        self._goals: dict[str, float] | None = None
        self._wake = threading.Event()
        self._next_read_s = 0.0
        bus.on_reply_wait(self._send_goals)

    def _send_goals(self) -> None:
        """Send the newest goals, if the loop gave any since the last sent (none once stopped:
        the safe state holds the servos where they are)."""
        if self._stop.is_set():
            return
        with self._goal_lock:
            goals, self._goals = self._goals, None
        if goals:
            self._send(goals)

    def _send(self, goals: dict[str, float]) -> None:
        """Send ``goals`` and queue them as a ``servo_goals`` sample stamped when they went
        onto the bus, which the estimator takes them from."""
        self.bus.command_lengths(goals)
        self.out.put(Sample("servo_goals", self.bus.goals_sent_ns, goals))

    def command(self, lengths_m: dict[str, float]) -> None:
        """Queue string length goals (name -> m); only the newest is sent, at once: the
        estimator takes a command from the tick that made it, so a goal held back to the next
        read (up to a read period) would lead the filter's rest lengths by that much."""
        with self._goal_lock:
            self._goals = dict(lengths_m)
        self._wake.set()

    def stop(self, timeout_s: float = 2.0) -> None:
        self._stop.set()
        self._wake.set()
        super().stop(timeout_s)
        self.bus.on_reply_wait(None)

    def _cycle(self) -> None:
        self._wake.clear()  # before taking the goals: a command after this wakes the next wait
        with self._goal_lock:
            goals, self._goals = self._goals, None
        now = time.monotonic()
        read = now >= self._next_read_s
        try:
            if goals:
                self._send(goals)
            if read:
                self._next_read_s = max(self._next_read_s, now) + self.period_s
                states = self.bus.read_states()
        except ServoTimeoutError as exc:
            raise DeviceFault("servos", f"{exc}: silent, declared at its first time-out") from exc
        except ServoCommError:
            self.comm_errors += 1
            self.comm_errors_total += 1
            if self.comm_errors >= self.max_comm_errors:
                raise
            with self._goal_lock:
                self._goals = self._goals or goals  # resend them next cycle
        else:
            if read:
                self.comm_errors = 0
                # stamped when the servos sampled their positions, not when the loop got them
                t_ns = sum(s.t_ns for s in states) // max(len(states), 1)
                self.out.put(Sample("servos", t_ns, states))
        self._wake.wait(max(self._next_read_s - time.monotonic(), 0.0))
