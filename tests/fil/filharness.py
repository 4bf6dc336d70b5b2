"""Start and talk to the simavr firmware-in-the-loop harness (firmware/build/sim/fil_harness).

The harness prints ``PTY <path>`` once the UART0 pseudo-terminal exists, a ``STATS k=v ...``
line per simulated second, ``OK ...`` for each accepted stdin command and ``FINAL k=v ...`` at exit.
Nothing here builds anything: ``make -C firmware check`` does.
"""

from __future__ import annotations

import queue
import signal
import subprocess
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE = ROOT / "firmware"
HARNESS = FIRMWARE / "build" / "sim" / "fil_harness"
SELFTEST_ELF = FIRMWARE / "build" / "sim" / "selftest.elf"
AVR_BUILD = FIRMWARE / "build" / "avr"


class HarnessError(RuntimeError):
    """The harness or the firmware ELF is missing, or the harness misbehaved."""


def require_file(path: Path, what: str) -> Path:
    """Return ``path`` or raise naming the missing file and how to build it."""
    if not path.is_file():
        raise HarnessError(f"{what} missing: {path} (build it with `make -C firmware check`)")
    return path


def firmware_elf() -> Path:
    """The wheel-board firmware ELF in firmware/build/avr (exactly one ``*.elf`` expected)."""
    elfs = sorted(AVR_BUILD.glob("*.elf")) if AVR_BUILD.is_dir() else []
    if len(elfs) != 1:
        found = ", ".join(p.name for p in elfs) or "none"
        raise HarnessError(
            f"want exactly one firmware ELF in {AVR_BUILD}, found {found} "
            "(build it with `make -C firmware check`)"
        )
    return elfs[0]


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


class Harness:
    """One running harness process; use as a context manager.

    Parameters
    ----------
    elf : Path
        Firmware to run.
    args : list of str
        Extra harness options (``--free``, ``--rate 2``, ``--enc-fault 1:error`` ...).
    """

    def __init__(self, elf: Path, args: list[str] | None = None, start_timeout_s: float = 10.0):
        require_file(HARNESS, "FIL harness")
        require_file(elf, "firmware ELF")
        self.lines: queue.Queue[str] = queue.Queue()
        self.stats: list[dict[str, str]] = []
        self.final: dict[str, str] | None = None
        self.log: list[str] = []
        self.proc = subprocess.Popen(
            [str(HARNESS), *(args or []), str(elf)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            bufsize=1,
        )
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self.pty = self._wait_pty(start_timeout_s)

    def _read(self) -> None:
        for raw in self.proc.stdout:
            line = raw.rstrip("\n")
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
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._reader.join(timeout=timeout_s)
        return self.final

    def __enter__(self) -> Harness:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
