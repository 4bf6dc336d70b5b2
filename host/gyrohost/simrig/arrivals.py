"""Arrival times of the bytes a driver writes to an emulator's pseudo-terminal.

A device takes a driver's bytes when they arrive: a servo moves to a goal then, and samples the
position it reports then. A pty keeps no arrival times, and an emulator that steps a physics
model learns of bytes only at its next poll, a truth step (about a millisecond) later at worst.
:class:`ArrivalStamps` reads the pty's master in a small child process that does
nothing else, so it wakes as the bytes come and stamps them with ``time.monotonic()`` (a clock
every process on the machine shares), and passes them on down a pipe with their stamps.

The child runs :mod:`.stamp_child` as a script.
"""

import os
import select
import subprocess
import sys

from . import stamp_child
from .errors import PtyLinkError
from .stamp_child import RECORD

START_TIMEOUT_S = 5.0
"""Longest wait for the child to report that it reads the pty, s."""


class ArrivalStamps:
    """A child process reading the pty master ``master_fd`` and stamping what arrives.

    The parent keeps writing its replies to ``master_fd``; it must no longer read from it.

    Parameters
    ----------
    master_fd : int
    name : str
        What the errors call the pty (its slave's path).

    Raises
    ------
    PtyLinkError
        The child did not report ready in time.
    OSError
        The child could not be started.
    """

    def __init__(self, master_fd: int, name: str = "a pty") -> None:
        self.name = name
        records_r, records_w = os.pipe()
        stop_r, stop_w = os.pipe()
        try:
            self._proc = subprocess.Popen(
                [
                    sys.executable,
                    "-I",
                    "-S",
                    stamp_child.__file__,
                    *map(str, (master_fd, records_w, stop_r)),
                ],
                pass_fds=(master_fd, records_w, stop_r),
                start_new_session=True,  # a Ctrl-C at the terminal is the rig's to handle
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,  # its end is the parent's to report (take)
            )
        finally:
            os.close(records_w)
            os.close(stop_r)
        self._records, self._stop, self._buffer = records_r, stop_w, b""
        ready, _, _ = select.select([records_r], [], [], START_TIMEOUT_S)
        if not ready or os.read(records_r, 1) != b"R":
            self.close()
            raise PtyLinkError(f"the arrival-stamping child of {name} did not start")
        os.set_blocking(records_r, False)

    def fileno(self) -> int:
        """The records pipe's descriptor, for ``select`` over several inputs."""
        return self._records

    def take(self) -> list[tuple[float, bytes]]:
        """Every whole record arrived so far: (arrival stamp, s of ``time.monotonic()``, bytes),
        oldest first.

        Raises
        ------
        PtyLinkError
            The child has stopped: no bytes would be taken any more.
        """
        while True:
            try:
                chunk = os.read(self._records, 65536)
            except BlockingIOError:
                break
            if not chunk:
                raise PtyLinkError(
                    f"the arrival-stamping child of {self.name} stopped "
                    f"(exit code {self._proc.poll()})"
                )
            self._buffer += chunk
        out, view = [], self._buffer
        while len(view) >= RECORD.size:
            stamp, n = RECORD.unpack_from(view)
            if len(view) < RECORD.size + n:
                break
            out.append((stamp, bytes(view[RECORD.size : RECORD.size + n])))
            view = view[RECORD.size + n :]
        self._buffer = view
        return out

    def close(self) -> None:
        """Stop the child and wait for it (idempotent)."""
        if self._stop is None:
            return
        os.close(self._stop)
        self._stop = None
        try:
            self._proc.wait(timeout=2.0)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
        os.close(self._records)
