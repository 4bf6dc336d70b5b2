"""Pseudo-terminal pair and the I/O loop shared by the device emulators.

The emulator owns the master side of a pty; the driver under test opens ``slave_path`` like any
serial port (pyserial or dynamixel-sdk). A pty ignores baud rate and latency, so delays and faults
are injected on purpose by a :class:`~gyrohost.simrig.faults.FaultFilter` on the emulator's write
side.

An emulator subclasses :class:`PtyDevice` and implements ``handle_rx`` (bytes the driver sent) and
``tick`` (periodic work such as emitting samples or moving a servo). It runs either in a background
thread (:meth:`PtyDevice.start`) or is polled by the caller (:meth:`PtyDevice.poll`), which makes
simulated-time runs deterministic.
"""

import errno
import os
import select
import sys
import threading
import time
import tty

from gyrohost.simrig.arrivals import ArrivalStamps
from gyrohost.simrig.faults import FaultFilter

from .errors import PtyLinkError

SWITCH_INTERVAL_S = 0.0005
"""GIL switch interval set while an emulator thread runs, s (see :meth:`PtyDevice.start`)."""


class PtyLink:
    """A raw pseudo-terminal pair; this object keeps both ends open until :meth:`close`.

    Keeping the slave end open means the master never sees end-of-file when a driver closes and
    reopens the port. Writes are non-blocking: when nobody reads the slave side and the kernel
    buffer is full, bytes are dropped and counted, as a real UART would lose them.
    """

    def __init__(self) -> None:
        try:
            self._master_fd, self._slave_fd = os.openpty()
        except OSError as exc:
            raise PtyLinkError(f"cannot create a pseudo-terminal pair: {exc}") from exc
        tty.setraw(self._slave_fd)  # no echo, no line discipline: bytes pass unchanged
        os.set_blocking(self._master_fd, False)
        self.slave_path = os.ttyname(self._slave_fd)
        self.overflow_bytes = 0
        self._closed = False

    def fileno(self) -> int:
        """The master's file descriptor, for ``select`` over several links."""
        return self._master_fd

    def write(self, data: bytes) -> int:
        """Write to the driver's side; return the number of bytes accepted (rest counted lost)."""
        if self._closed or not data:
            return 0
        try:
            n = os.write(self._master_fd, data)
        except BlockingIOError:
            n = 0
        except OSError as exc:
            if exc.errno in (errno.EIO, errno.EBADF):
                n = 0
            else:
                raise PtyLinkError(f"write to {self.slave_path} master failed: {exc}") from exc
        self.overflow_bytes += len(data) - n
        return n

    def read(self, timeout_s: float = 0.0) -> bytes:
        """Read what the driver wrote, waiting at most ``timeout_s`` s; ``b""`` if nothing came."""
        if self._closed:
            return b""
        ready, _, _ = select.select([self._master_fd], [], [], max(timeout_s, 0.0))
        if not ready:
            return b""
        try:
            return os.read(self._master_fd, 4096)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError as exc:
            if exc.errno == errno.EIO:  # slave side hung up: nothing to read
                return b""
            raise PtyLinkError(f"read from {self.slave_path} master failed: {exc}") from exc

    def close(self) -> None:
        """Close both ends (idempotent)."""
        if self._closed:
            return
        self._closed = True
        for fd in (self._master_fd, self._slave_fd):
            try:
                os.close(fd)
            except OSError:
                pass


class PtyDevice:
    """Base of an emulated serial device on a :class:`PtyLink`.

    Parameters
    ----------
    faults : FaultFilter, optional
        Filter applied to every byte the device sends; a transparent filter by default.
    """

    FRAME_END: int | None = None
    """The byte that ends every frame the driver sends, for a protocol that has one (COBS'
    0x00); it places the frames read at once in time (:meth:`poll`)."""
    next_send_s: float | None = None
    """When the device's next sample is whole for the host, s, for a device that streams on its
    own clock (None: it answers, or has nothing due); the simulated rig's loop wakes then."""

    def __init__(self, faults: FaultFilter | None = None) -> None:
        self.link = PtyLink()
        self.faults = faults if faults is not None else FaultFilter()
        self.lock = threading.RLock()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._polled_s: float | None = None
        self._stamps: ArrivalStamps | None = None
        self._origin_s = 0.0
        self._arrived: list[tuple[float, bytes]] = []
        self.loop_error: BaseException | None = None

    @property
    def slave_path(self) -> str:
        """Path of the pty slave: give this to the driver as its serial port."""
        return self.link.slave_path

    # --- to be implemented by an emulator -------------------------------------------------
    def handle_rx(self, data: bytes, now_s: float) -> None:
        """Consume bytes the driver sent (called with ``lock`` held)."""
        raise NotImplementedError

    def tick(self, now_s: float) -> None:
        """Periodic work at time ``now_s`` s (called with ``lock`` held)."""
        raise NotImplementedError

    # --- shared machinery -----------------------------------------------------------------
    def send(self, data: bytes, now_s: float) -> None:
        """Send bytes to the driver through the fault filter."""
        self.link.write(self.faults.process(data, now_s))

    def poll(
        self, now_s: float | None = None, timeout_s: float = 0.0, present_s: float | None = None
    ) -> None:
        """Run one iteration: read input (waiting up to ``timeout_s`` s), tick, release stalls.

        The bytes read came in since the last poll. As on a board whose tick interrupt and UART
        run side by side, the ticks run up to each frame's arrival before the frame is handled.
        Bytes stamped where they arrived (:meth:`stamp_arrivals`) are taken at their stamps.
        Otherwise, as a pty keeps no arrival times: with :attr:`FRAME_END` set, a frame is
        taken as arrived when its last byte did, the bytes spread evenly over the time since
        the last poll (a steady sender's); otherwise all at the poll's time: the rig's loop
        wakes when bytes come in, so that is when they came to the wake-up's latency, where the
        last poll's time would place a request before it was sent (a servo's read showing where
        it was up to a poll earlier, a goal moving it before the host sent it). After the
        emulator was held up (a loaded CPU), delimited frames the driver sent meanwhile keep
        their spacing among the ticks instead of all arriving after the whole gap: a board's
        heartbeat timer, say, counts the silence between them, not the emulator's. A silence of
        the driver within such a gap is seen where the frames of the gap are too few to cover
        it (a lone frame after a long gap arrives at its end), not where they crowd at one end
        of it.

        Parameters
        ----------
        now_s : float, optional
            Emulator time, s; ``time.monotonic()`` when omitted (read after the wait).
        timeout_s : float
            Longest wait for input, s.
        present_s : float, optional
            The rig's present, s, where ``now_s`` is a truth step's end behind it (the rig's
            loop stepping its truth): a device that takes bytes as arriving at the poll's time
            runs to the present instead, where they came (read at the step's end, a goal moved
            the servo before the host sent it, by up to a hold-up), and keeps its path for the
            step (:meth:`.servo_emu.Mx12Bus.lengths_at`).
        """
        data = self.link.read(timeout_s) if self._stamps is None else b""
        t = time.monotonic() if now_s is None else now_s
        if present_s is not None and self.FRAME_END is None:
            t = max(t, present_s)
        with self.lock:
            since = t if self._polled_s is None else min(self._polled_s, t)
            self._polled_s = t
            if self._stamps is None:
                arrivals = self._arrivals(data, since, t)
            else:
                arrivals = self._stamped(since, t)
            for arrived_s, frames in arrivals:
                self.tick(arrived_s)
                self.handle_rx(frames, arrived_s)
            self.tick(t)
            self.link.write(self.faults.release(t))

    def stamp_arrivals(self, origin_s: float) -> None:
        """From now on take the driver's bytes at the times they arrived, stamped by a child
        process (:class:`~gyrohost.simrig.arrivals.ArrivalStamps`), rather than as arriving at
        :meth:`poll`; ``origin_s`` is ``time.monotonic()`` at the caller's time zero (a poll's
        ``now_s``). Bytes stamped after a poll's time wait for a later poll."""
        if self._stamps is None:
            self._stamps = ArrivalStamps(self.link.fileno(), self.link.slave_path)
            self._origin_s = origin_s

    def waitable(self):
        """What to ``select`` on for the driver's input: the stamped arrivals' pipe or the
        link."""
        return self.link if self._stamps is None else self._stamps

    def _stamped(self, since_s: float, now_s: float) -> list[tuple[float, bytes]]:
        """The stamped arrivals up to ``now_s``, each at its time or, stamped before the last
        poll (the child was slow to pass it on), at ``since_s``."""
        self._arrived += [(stamp - self._origin_s, data) for stamp, data in self._stamps.take()]
        due = [(max(t, since_s), data) for t, data in self._arrived if t <= now_s]
        self._arrived = self._arrived[len(due) :]
        return due

    def _arrivals(self, data: bytes, since_s: float, now_s: float) -> list[tuple[float, bytes]]:
        """``data`` cut after each :attr:`FRAME_END`, each piece with the time its last byte is
        taken to have arrived, s (see :meth:`poll`)."""
        if self.FRAME_END is None:
            return [(now_s, data)] if data else []
        pieces, start, n = [], 0, len(data)
        while start < n:
            end = data.find(self.FRAME_END, start) + 1 or n
            pieces.append((since_s + (now_s - since_s) * end / n, data[start:end]))
            start = end
        return pieces

    def start(self, period_s: float = 0.0005) -> "PtyDevice":
        """Run :meth:`poll` in a daemon thread until :meth:`stop`; returns ``self``.

        The thread shares the GIL with the driver, and dynamixel-sdk busy-waits for replies
        holding it. With the default 5 ms switch interval, the few GIL hand-overs of one reply
        can approach the SDK's 34 ms timeout on a loaded machine, so this lowers the
        interpreter's switch interval to at most ``SWITCH_INTERVAL_S`` (process-wide).
        """
        if self._thread is not None:
            return self
        if sys.getswitchinterval() > SWITCH_INTERVAL_S:
            sys.setswitchinterval(SWITCH_INTERVAL_S)
        self._stop.clear()
        self._thread = threading.Thread(
            target=self._run, args=(period_s,), name=type(self).__name__, daemon=True
        )
        self._thread.start()
        return self

    def _run(self, period_s: float) -> None:
        try:
            while not self._stop.is_set():
                self.poll(timeout_s=period_s)
        except BaseException as exc:  # kept for the owner to report; the thread must not vanish
            self.loop_error = exc

    def stop(self) -> None:
        """Stop the background thread (if any) and wait for it."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None

    def close(self) -> None:
        """Stop and close the pty pair."""
        self.stop()
        if self._stamps is not None:
            self._stamps.close()
            self._stamps = None
        self.link.close()

    def __enter__(self) -> "PtyDevice":
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
