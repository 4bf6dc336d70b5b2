"""Arrival times of the bytes a driver writes to an emulator's pseudo-terminal.

A device takes a driver's bytes when they arrive: a servo moves to a goal then, and samples the
position it reports then. A pty keeps no arrival times, and an emulator that steps a physics
model learns of bytes only at its next poll: the simulated rig's loop, busy with a truth step
(0.8 ms, up to 2 ms on two cores), took a servo goal up to 3 ms after the host wrote it, 0.4 ms
on average. :class:`ArrivalStamps` reads the pty's master in a small child process that does
nothing else, so it wakes as the bytes come and stamps them with ``time.monotonic()`` (a clock
every process on the machine shares), and passes them on down a pipe with their stamps.

The child runs this file as a script (standard library only, no package import: it starts in a
few tens of milliseconds) with three inherited descriptors: the pty's master to read, the pipe
to write records to, and a pipe from the parent whose end-of-file tells it to stop (the parent
closing it, or dying).
"""

import os
import select
import struct
import subprocess
import sys
import time

RECORD = struct.Struct("<dH")
"""A record's header: the arrival stamp (``time.monotonic()``, s) and the byte count."""
READ_SIZE = 4000
"""Most bytes read into one record: header and bytes stay within an atomic pipe write."""
START_TIMEOUT_S = 5.0
"""Longest wait for the child to report that it reads the pty, s."""


class ArrivalStamps:
    """A child process reading the pty master ``master_fd`` and stamping what arrives.

    The parent keeps writing its replies to ``master_fd``; it must no longer read from it.

    Raises
    ------
    OSError
        The child could not be started or did not report ready in time.
    """

    def __init__(self, master_fd: int) -> None:
        records_r, records_w = os.pipe()
        stop_r, stop_w = os.pipe()
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-I", "-S", __file__, str(master_fd), str(records_w), str(stop_r)],
                pass_fds=(master_fd, records_w, stop_r),
                start_new_session=True,  # a Ctrl-C at the terminal is the rig's to handle
                stdin=subprocess.DEVNULL,
            )
        finally:
            os.close(records_w)
            os.close(stop_r)
        self._records, self._stop, self._buffer = records_r, stop_w, b""
        ready, _, _ = select.select([records_r], [], [], START_TIMEOUT_S)
        if not ready or os.read(records_r, 1) != b"R":
            self.close()
            raise OSError(f"the arrival-stamping child for pty fd {master_fd} did not start")
        os.set_blocking(records_r, False)

    def fileno(self) -> int:
        """The records pipe's descriptor, for ``select`` over several inputs."""
        return self._records

    def take(self) -> list[tuple[float, bytes]]:
        """Every whole record arrived so far: (arrival stamp, s of ``time.monotonic()``, bytes),
        oldest first."""
        try:
            while chunk := os.read(self._records, 65536):
                self._buffer += chunk
        except BlockingIOError:
            pass
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


def _serve(master_fd: int, records_fd: int, stop_fd: int) -> None:
    """The child: read the master as bytes come, write stamped records, until told to stop."""
    os.write(records_fd, b"R")
    while True:
        ready, _, _ = select.select([master_fd, stop_fd], [], [])
        if stop_fd in ready:
            return
        try:
            data = os.read(master_fd, READ_SIZE)
        except BlockingIOError:
            continue
        except OSError:  # the driver's side hung up (EIO): nothing to read until it reopens
            time.sleep(0.001)
            continue
        if data:
            os.write(records_fd, RECORD.pack(time.monotonic(), len(data)) + data)


if __name__ == "__main__":
    try:
        _serve(*(int(arg) for arg in sys.argv[1:4]))
    except (BrokenPipeError, KeyboardInterrupt):  # the parent is gone
        pass
