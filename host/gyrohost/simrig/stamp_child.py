"""The child process of :class:`~gyrohost.simrig.arrivals.ArrivalStamps`: it reads a pty's
master as bytes come, stamps them with ``time.monotonic()`` and writes them down a pipe as
records, until the parent closes its stop pipe (or dies).

Run as a script with three inherited descriptors: the master, the records pipe, the stop pipe.
Standard library only, no package import: it starts in a few tens of milliseconds.
"""

import os
import select
import struct
import sys
import time

RECORD = struct.Struct("<dH")
"""A record's header: the arrival stamp (``time.monotonic()``, s) and the byte count."""
READ_SIZE = 4000
"""Most bytes read into one record: header and bytes stay within an atomic pipe write."""


def serve(master_fd: int, records_fd: int, stop_fd: int) -> None:
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
        serve(*(int(arg) for arg in sys.argv[1:4]))
    except (BrokenPipeError, KeyboardInterrupt):  # the parent is gone
        pass
