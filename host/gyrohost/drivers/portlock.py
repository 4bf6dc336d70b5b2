"""One process at a time on a serial device: a lock file per port, and the port opened exclusively.

Two hosts on one port read each other's bytes: a second ``gyrotens run`` on a live rig stole
the first one's telemetry frames and could have sent HELLO or servo goals in the middle of its
run. So every driver opens its port through this module:

- a lock file per port (:func:`lock_path`, in the user's runtime directory) holding the PID and
  command line of the process that has the port, locked with ``flock``: the kernel drops the
  ``flock`` when that process dies, however it dies, so a lock file left by a dead process is
  taken over without a word, and a live holder is named in the refusal;
- the port itself opened with pyserial's ``exclusive=True`` (an ``flock`` on the device, on
  POSIX), which also keeps out a program that does not know these lock files.

Within one process a port may be claimed again (the run claims all its ports before any driver
opens one); the lock goes when the last claim is released. Elsewhere than on POSIX (Windows) a
serial port is opened exclusively by the system itself and no lock file is kept; ``fcntl`` is
imported only where it exists.
"""

import errno
import os
import shlex
import sys
import tempfile
import threading
from collections.abc import Mapping
from contextlib import ExitStack, contextmanager
from pathlib import Path
from urllib.parse import quote

import serial

from .errors import PortBusyError

EXCLUSIVE = os.name == "posix"
"""pyserial's ``exclusive`` option and ``flock`` exist on POSIX only (Windows opens ports
exclusively)."""


def runtime_dir() -> Path:
    """The user's runtime directory for gyrotens: ``$XDG_RUNTIME_DIR/gyrotens``, else
    ``<tmp>/gyrotens-<uid>`` (``<tmp>/gyrotens`` where there are no user ids: Windows' temporary
    folder is the user's own)."""
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime:
        return Path(runtime) / "gyrotens"
    uid = f"-{os.getuid()}" if hasattr(os, "getuid") else ""
    return Path(tempfile.gettempdir()) / f"gyrotens{uid}"


def lock_path(port: str) -> Path:
    """The lock file of ``port``: named after the device it resolves to (a by-id link and its
    ``/dev/ttyUSB0`` share one lock)."""
    return runtime_dir() / "locks" / f"{quote(os.path.realpath(port), safe='')}.lock"


_held: dict[Path, list] = {}  # lock path -> [file descriptor, claims] of this process
_held_guard = threading.Lock()


class PortClaim:
    """This process's claim on ``port``; :meth:`release` gives it up (idempotent).

    Raises
    ------
    PortBusyError
        Another live process holds the port's lock file: the message names the port, that
        process's PID and command line.
    """

    def __init__(self, port: str):
        self.port = str(port)
        self.path = lock_path(self.port)
        self._released = not EXCLUSIVE  # no lock files there: nothing to hold
        if self._released:
            return
        with _held_guard:
            if self.path in _held:
                _held[self.path][1] += 1
            else:
                _held[self.path] = [_take(self.path, self.port), 1]

    def release(self) -> None:
        with _held_guard:
            if self._released:
                return
            self._released = True
            entry = _held[self.path]
            entry[1] -= 1
            if entry[1] == 0:
                del _held[self.path]
                _give_up(self.path, entry[0])


def _take(path: Path, port: str) -> int:
    """Lock the file at ``path`` for this process and write who holds it; its descriptor."""
    import fcntl  # POSIX only (PortClaim asks for no lock elsewhere)

    path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.read(fd, 4096).decode(errors="replace")
            os.close(fd)
            raise PortBusyError(port, *_holder(holder), path) from None
        if _same_file(fd, path):
            break
        os.close(fd)  # the holder removed the file between our open and our lock: anew
    os.ftruncate(fd, 0)  # what a dead holder left
    os.write(fd, f"{os.getpid()}\n{_command_line()}\n".encode())
    return fd


def _same_file(fd: int, path: Path) -> bool:
    try:
        return os.fstat(fd).st_ino == os.stat(path).st_ino
    except FileNotFoundError:
        return False


def _give_up(path: Path, fd: int) -> None:
    """Remove the lock file while still holding it (a waiting process then sees a file that is
    no longer the lock and retries on a new one), then unlock."""
    try:
        path.unlink()
    except FileNotFoundError:
        pass
    os.close(fd)


def _holder(text: str) -> tuple[str, str]:
    """PID and command line from a lock file's text (unknown while the holder writes them)."""
    lines = text.splitlines()
    pid = lines[0].strip() if lines and lines[0].strip() else "unknown"
    return pid, (lines[1] if len(lines) > 1 else "")


def _command_line() -> str:
    """This process's command line on one line (a ``python -c`` script holds newlines)."""
    return " ".join(shlex.join(getattr(sys, "orig_argv", sys.argv)).split())


@contextmanager
def claim_ports(ports: Mapping[str, str]):
    """Claim every port of ``ports`` (name -> path) for the block, before any is opened; a
    refusal names the port's key."""
    with ExitStack() as stack:
        for key, port in ports.items():
            try:
                claim = PortClaim(port)
            except PortBusyError as exc:
                raise PortBusyError(port, exc.pid, exc.command, exc.lock, key) from None
            stack.callback(claim.release)
        yield


def exclusive_serial(port: str, baudrate: int, **options) -> serial.Serial:
    """A pyserial port opened exclusively (no lock file: the caller holds a :class:`PortClaim`).

    Raises
    ------
    PortBusyError
        Another program has the device open exclusively.
    """
    if EXCLUSIVE:
        options["exclusive"] = True
    try:
        return serial.Serial(port, baudrate, **options)
    except serial.SerialException as exc:
        if exc.errno in (errno.EAGAIN, errno.EWOULDBLOCK):
            raise PortBusyError(port, "", "", None) from None
        raise


class LockedSerial:
    """A serial port held for this process: the lock file claimed, then the port opened
    exclusively; :meth:`close` closes it and releases the claim. Everything else is the pyserial
    port's (``read``, ``write``, ``in_waiting``, ``baudrate``, ...)."""

    def __init__(self, port: str, baudrate: int, **options):
        claim = PortClaim(port)
        try:
            serial_port = exclusive_serial(port, baudrate, **options)
        except BaseException:
            claim.release()
            raise
        object.__setattr__(self, "_serial", serial_port)
        object.__setattr__(self, "_claim", claim)

    def close(self) -> None:
        try:
            self._serial.close()
        finally:
            self._claim.release()

    def __getattr__(self, name: str):
        return getattr(self._serial, name)

    def __setattr__(self, name: str, value) -> None:
        setattr(self._serial, name, value)

    def __enter__(self) -> "LockedSerial":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
