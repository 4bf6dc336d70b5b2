"""The real wheel-board firmware in simavr: the FIL harness process, and the rig's wheel board.

The harness ``sim/fil_harness`` of a firmware build (source ``firmware/sim/fil_harness.c``,
docs/fil.md) runs the firmware ELF in simavr with four encoder and motor models and exposes UART0
as a pseudo-terminal.
It prints ``PTY <path>`` once that pty exists, a ``STATS k=v ...`` line every ``--stats-period``
simulated seconds, with ``--speed-period`` a ``SPEED t_us w0 w1 w2 w3 frames`` line (the motor
models' true speeds, rad/s, and the frames the firmware has sent), ``OK ...``/``ERR ...`` for each
stdin command and ``FINAL k=v ...`` at exit. Nothing here builds anything:
``make -C firmware check`` does, into ``firmware/build``.

The binaries are found through settings, never through where this file sits: the
``[sim.wheels] simavr_elf``/``simavr_harness`` keys of the rig configuration, else the firmware
build directory named by the ``GYROTENS_FIRMWARE_BUILD`` environment variable (holding
``avr/*.elf`` and ``sim/fil_harness``; ``gyrotens rig --firmware-build DIR`` sets the keys from
one); with none of them :class:`HarnessError` says what to set.

:class:`Harness` starts and talks to one harness process (used by ``tests/fil`` and the rig);
:class:`SimavrWheelBoard` is the simulated rig's wheel board when ``[sim.wheels] kind =
"simavr"``: the host opens the harness's pty directly, and the truth model reads the wheel speeds
from the SPEED lines.
"""

from __future__ import annotations

import math
import os
import queue
import signal
import subprocess
import threading
import time
import weakref
from dataclasses import dataclass
from pathlib import Path

from .errors import HarnessError

FIRMWARE_BUILD_ENV = "GYROTENS_FIRMWARE_BUILD"
"""Environment variable naming a firmware build directory (``avr/*.elf``, ``sim/fil_harness``)."""
BUILD_HINT = "build it with `make -C firmware check`"

SPEED_PERIOD_S = 0.01
"""Simulated seconds between the harness's SPEED lines in the rig (100 Hz)."""
UART_WAIT_MAX_S = 0.2
"""Rig: longest wait of the harness for a pty reader; then, with no host, output is dropped."""


def require_file(path: Path, what: str) -> Path:
    """Return ``path`` or raise naming the missing file and how to build it."""
    if not Path(path).is_file():
        raise HarnessError(f"{what} missing: {path} ({BUILD_HINT})")
    return Path(path)


def firmware_build() -> Path:
    """The firmware build directory named by ``$GYROTENS_FIRMWARE_BUILD``.

    Raises
    ------
    HarnessError
        The variable is not set: the message says what to set and how to build.
    """
    value = os.environ.get(FIRMWARE_BUILD_ENV, "")
    if not value:
        raise HarnessError(
            f"no firmware build to run in simavr: set {FIRMWARE_BUILD_ENV} to a firmware build "
            "directory (holding avr/*.elf and sim/fil_harness), or give "
            "`gyrotens rig --firmware-build DIR`, or set [sim.wheels] simavr_elf and "
            "simavr_harness in the rig configuration; in a checkout, `make -C firmware check` "
            "builds one in firmware/build"
        )
    return Path(value).expanduser()


def harness_binary(build_dir: Path | None = None) -> Path:
    """The FIL harness of ``build_dir`` (default :func:`firmware_build`); it must exist."""
    return require_file((build_dir or firmware_build()) / "sim" / "fil_harness", "FIL harness")


def firmware_elf(avr_dir: Path | None = None) -> Path:
    """The wheel-board firmware ELF in ``avr_dir`` (exactly one ``*.elf`` expected).

    ``avr_dir`` defaults to ``avr/`` of :func:`firmware_build`.
    """
    build_dir = avr_dir or firmware_build() / "avr"
    elfs = sorted(build_dir.glob("*.elf")) if build_dir.is_dir() else []
    if len(elfs) != 1:
        found = ", ".join(p.name for p in elfs) or "none"
        raise HarnessError(
            f"want exactly one firmware ELF in {build_dir}, found {found} ({BUILD_HINT})"
        )
    return elfs[0]


def build_binaries(build_dir: Path) -> tuple[Path, Path]:
    """Firmware ELF and FIL harness of the firmware build directory ``build_dir``.

    Raises
    ------
    HarnessError
        Either is missing (the message names it and the make command).
    """
    return firmware_elf(build_dir / "avr"), harness_binary(build_dir)


def parse_kv(line: str) -> dict[str, str]:
    """``'STATS t_s=1.0 rpm=1,2'`` -> ``{'tag': 'STATS', 't_s': '1.0', 'rpm': '1,2'}``."""
    tag, *fields = line.split()
    out = {"tag": tag}
    for field in fields:
        key, _, value = field.partition("=")
        out[key] = value
    return out


def stats_rpm(stats: dict[str, str]) -> list[float]:
    """True rotor speeds of the four motors from a STATS/FINAL line, rpm."""
    return [float(v) for v in stats["rpm"].split(",")]


@dataclass(frozen=True)
class SpeedSample:
    """One ``SPEED`` line.

    Attributes
    ----------
    t_us : int, us
        Simulated (firmware) time.
    omega_rad_s : tuple of 4 float, rad/s
        True rotor speeds of the harness's motor models, motor order.
    frames : int
        Frames the firmware has sent on UART0 so far (counted at their 0x00 delimiters).
    """

    t_us: int
    omega_rad_s: tuple[float, float, float, float]
    frames: int


def parse_speed(line: str) -> SpeedSample:
    """``'SPEED 10000 1.0 2.0 3.0 4.0 5'`` -> :class:`SpeedSample`."""
    words = line.split()
    if len(words) != 7 or words[0] != "SPEED":
        raise HarnessError(f"malformed SPEED line: {line!r}")
    omega = tuple(float(w) for w in words[2:6])
    return SpeedSample(int(words[1]), omega, int(words[6]))


def _stop_process(proc: subprocess.Popen, timeout_s: float) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


class Harness:
    """One running harness process; use as a context manager.

    Parameters
    ----------
    elf : Path
        Firmware to run.
    args : list of str
        Extra harness options (``--free``, ``--rate 2``, ``--enc-fault 1:error`` ...).
    start_timeout_s : float, s
        Longest wait for the ``PTY`` line.
    harness : Path, optional
        Harness binary; :func:`harness_binary` (``$GYROTENS_FIRMWARE_BUILD``) by default.

    Attributes
    ----------
    pty : str
        UART0 pseudo-terminal: the wheel board's serial port.
    stats : list of dict
        Every ``STATS`` line so far (:func:`parse_kv`).
    speed : SpeedSample or None
        The latest ``SPEED`` line (only with ``--speed-period``); SPEED lines are not logged.
    final : dict or None
        The ``FINAL`` line once the harness has exited.
    log : list of str
        Every other line of output (stderr included).
    """

    def __init__(
        self,
        elf: Path,
        args: list[str] | None = None,
        start_timeout_s: float = 10.0,
        harness: Path | None = None,
    ):
        binary = require_file(harness, "FIL harness") if harness else harness_binary()
        require_file(elf, "firmware ELF")
        self.lines: queue.Queue[str] = queue.Queue()
        self.stats: list[dict[str, str]] = []
        self.speed: SpeedSample | None = None
        self.final: dict[str, str] | None = None
        self.log: list[str] = []
        self.proc = subprocess.Popen(
            [str(binary), *(args or []), str(elf)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            bufsize=1,
        )
        # a forgotten harness would run on at real time after the interpreter exits
        self._finalizer = weakref.finalize(self, _stop_process, self.proc, 2.0)
        self._reader = threading.Thread(target=self._read, name="fil-harness", daemon=True)
        self._reader.start()
        self.pty = self._wait_pty(start_timeout_s)

    def _read(self) -> None:
        for raw in self.proc.stdout:
            line = raw.rstrip("\n")
            if line.startswith("SPEED "):
                self.speed = parse_speed(line)
                continue
            self.log.append(line)
            if line.startswith("STATS "):
                self.stats.append(parse_kv(line))
            elif line.startswith("FINAL "):
                self.final = parse_kv(line)
            self.lines.put(line)

    def _wait_pty(self, timeout_s: float) -> str:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.1)
            except queue.Empty:
                if self.proc.poll() is not None:
                    break
                continue
            if line.startswith("PTY "):
                return line.split()[1]
        self.stop()
        raise HarnessError("harness printed no PTY line; output:\n" + "\n".join(self.log))

    def running(self) -> bool:
        """True while the harness process has not exited."""
        return self.proc.poll() is None

    def command(self, text: str, timeout_s: float = 5.0) -> str:
        """Send one stdin command and return the harness's ``OK``/``ERR`` answer."""
        self.proc.stdin.write(text + "\n")
        self.proc.stdin.flush()
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.1)
            except queue.Empty:
                continue
            if line.startswith(("OK ", "ERR ")):
                return line
        raise HarnessError(f"no answer to harness command {text!r}")

    def latest_stats(self, timeout_s: float = 5.0) -> dict[str, str]:
        """Wait for the next STATS line and return it."""
        n = len(self.stats)
        deadline = time.monotonic() + timeout_s
        while len(self.stats) == n:
            if time.monotonic() > deadline or self.proc.poll() is not None:
                raise HarnessError("harness printed no STATS line; output:\n" + self.tail())
            time.sleep(0.02)
        return self.stats[-1]

    def sim_time_s(self) -> float:
        """Simulated time of the latest STATS line, s."""
        return float(self.stats[-1]["t_s"]) if self.stats else 0.0

    def tail(self, n: int = 20) -> str:
        return "\n".join(self.log[-n:])

    def stop(self, timeout_s: float = 5.0) -> dict[str, str] | None:
        """SIGTERM the harness, wait for it and return its FINAL line."""
        _stop_process(self.proc, timeout_s)
        self._reader.join(timeout=timeout_s)
        return self.final

    def __enter__(self) -> Harness:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


class SimavrWheelBoard:
    """The simulated rig's wheel board: the real firmware ELF in the simavr harness.

    The harness runs paced to wall time (the host's heartbeats and the firmware's heartbeat
    timeout are wall-clock), whatever the rig's clock; the host opens :attr:`slave_path`, the
    harness's own pty, so no byte passes through this process. The truth reads
    :meth:`wheel_speeds_rad_s`: the harness's motor models' true speeds from its SPEED lines.

    Parameters
    ----------
    elf, harness : Path
        Firmware ELF and harness binary (:func:`firmware_elf`, :func:`harness_binary`).
    options : sequence of str
        Extra harness options (motor constants: ``--kt 0.01`` ...; docs/fil.md).
    """

    link = None
    """No pty of this process to select on: the harness owns the wheel board's pty."""

    def __init__(self, elf: Path, harness: Path, options: tuple[str, ...] = ()) -> None:
        args = [
            *("--speed-period", f"{SPEED_PERIOD_S:g}"),
            *("--uart-wait-max", f"{UART_WAIT_MAX_S:g}"),
            *options,
        ]
        self.harness = Harness(elf, args, harness=harness)
        self._frames0: int | None = None
        try:
            set_factory_offsets(self.harness.pty, elec_offset_deg(options))
        except BaseException:
            self.harness.stop()
            raise

    next_send_s = None  # the harness streams on its own: the rig's loop need not wake for it

    @property
    def slave_path(self) -> str:
        """The harness's UART0 pty: the wheel board's serial port."""
        return self.harness.pty

    def wheel_speeds_rad_s(self, at_s: float | None = None) -> list[float]:
        """True motor speeds of the latest SPEED line, rad/s (zeros before the first; the
        harness reports its motors at its own rate, so ``at_s``, the emulated board's
        signature, is not used).

        Raises
        ------
        HarnessError
            The harness's motor model reported a non-finite speed (motor and time named).
        """
        sample = self.harness.speed
        if sample is None:
            return [0.0] * 4
        bad = [i for i, w in enumerate(sample.omega_rad_s) if not math.isfinite(w)]
        if bad:
            raise HarnessError(
                f"simavr motor {bad[0]} speed is {sample.omega_rad_s[bad[0]]} at firmware time "
                f"{sample.t_us * 1e-6:.6f} s"
            )
        return list(sample.omega_rad_s)

    @property
    def telemetry_sent(self) -> int:
        """Frames the firmware sent since the rig's first poll (telemetry and replies)."""
        sample = self.harness.speed
        if sample is None or self._frames0 is None:
            return 0
        return sample.frames - self._frames0

    def poll(
        self, now_s: float | None = None, timeout_s: float = 0.0, present_s: float | None = None
    ) -> None:
        """Check that the harness still runs (the rig loop calls this on every pass; the
        harness reads its own pty and keeps its own time, so the times are not used).

        Raises
        ------
        HarnessError
            The harness process has exited (its last output in the message).
        """
        if not self.harness.running():
            raise HarnessError(
                f"the simavr wheel board exited (status {self.harness.proc.returncode}); "
                f"output:\n{self.harness.tail()}"
            )
        if self._frames0 is None and self.harness.speed is not None:
            self._frames0 = self.harness.speed.frames

    def summary_line(self) -> str:
        """One line: firmware time, pace and control-step figures (FINAL once stopped)."""
        s = self.harness.final or (self.harness.stats[-1] if self.harness.stats else None)
        if s is None:
            return "wheels (simavr): no STATS line yet"
        return (
            f"wheels (simavr): firmware time {float(s['t_s']):.2f} s in {float(s['wall_s']):.2f} s "
            f"wall (rt {float(s['rt']):.2f}), control step {s['cyc_mean']} cycles mean, "
            f"{s['cyc_max']} max, {s['overruns']} overruns"
        )

    def close(self) -> None:
        """Stop the harness (idempotent)."""
        self.harness.stop()


def elec_offset_deg(options: tuple[str, ...]) -> float:
    """The harness's ``--elec-offset`` in ``options``, degrees (0 if absent)."""
    for i, opt in enumerate(options):
        if opt == "--elec-offset" and i + 1 < len(options):
            return float(options[i + 1])
        if opt.startswith("--elec-offset="):
            return float(opt.split("=", 1)[1])
    return 0.0


def set_enc_offsets(board, elec_offset_deg: float = 0.0) -> None:
    """Set the four ENC_OFFSETs of the harness's motors, as a calibrated board holds them.

    The harness starts with a blank EEPROM (PARAMS_DEFAULTED), and the firmware refuses
    closed-loop setpoints until the offsets are calibrated or set. A motor whose electrical angle
    is ``elec_offset_deg`` at encoder zero (the harness's ``--elec-offset``) needs
    ENC_OFFSET = -elec_offset (turn/65536).

    Parameters
    ----------
    board : anything with ``set_param(name, value)`` (a connected wheel-board client)
    """
    value = round(-elec_offset_deg / 360.0 * 65536) % 65536
    for w in range(4):
        board.set_param(f"ENC_OFFSET_M{w}", value)


def set_factory_offsets(port: str, elec_offset_deg: float) -> None:
    """:func:`set_enc_offsets` through a connection of its own: the simulated rig's board comes
    calibrated."""
    from gyrohost.drivers.wheelboard import WheelBoard

    board = WheelBoard(port, reply_timeout_s=3.0)
    try:
        board.connect()
        set_enc_offsets(board, elec_offset_deg)
    finally:
        board.close()


def simavr_wheel_board(elf: str, harness: str, options: tuple[str, ...], base: Path):
    """:class:`SimavrWheelBoard` from the ``[sim.wheels]`` keys.

    Relative paths are taken from ``base`` (the configuration file's folder); ``""`` = the
    binary of the build named by ``$GYROTENS_FIRMWARE_BUILD``.

    Raises
    ------
    HarnessError
        A binary is missing (the message names it and the make command), or the harness did
        not start.
    """
    elf_path = base / elf if elf else firmware_elf()
    harness_path = base / harness if harness else harness_binary()
    return SimavrWheelBoard(elf_path, harness_path, options)
