"""Byte-stream fault injection, applied on an emulator's write side.

One :class:`FaultFilter` sits between an emulator and its pty: every byte the device sends passes
:meth:`FaultFilter.process`. Configured faults (:class:`.config.StreamFaultConfig`) act
continuously; run-time hooks act once or until switched off:

- corruption: a byte is XORed with a random non-zero mask (``corrupt_byte_prob``, ``corrupt_next``);
- loss: a byte vanishes (``drop_byte_prob``, ``drop_next``);
- silence: everything vanishes (``silent``, ``set_silent``);
- stalls like a Bluetooth link: bytes are held and then delivered as one burst
  (``stall_period_s``/``stall_duration_s``, ``stall_for``).

Device-level faults (servo overload, a servo that does not answer) live in the emulators, since
they change what the device says rather than how the bytes travel.
"""

import random
import threading
from dataclasses import dataclass

from gyrohost.simrig.config import StreamFaultConfig


@dataclass
class FaultCounters:
    """What the filter did so far (bytes, bursts)."""

    corrupted: int = 0
    dropped: int = 0
    silenced: int = 0
    stalled: int = 0
    bursts: int = 0


class FaultFilter:
    """Apply stream faults to outgoing bytes.

    Parameters
    ----------
    config : StreamFaultConfig, optional
        Continuous faults; none by default.
    """

    def __init__(self, config: StreamFaultConfig | None = None) -> None:
        cfg = config if config is not None else StreamFaultConfig()
        self.corrupt_byte_prob = cfg.corrupt_byte_prob
        self.drop_byte_prob = cfg.drop_byte_prob
        self.silent = cfg.silent
        self.stall_period_s = cfg.stall_period_s
        self.stall_duration_s = cfg.stall_duration_s
        self.counters = FaultCounters()
        self._rng = random.Random(cfg.seed)
        self._lock = threading.Lock()
        self._corrupt_pending = 0
        self._drop_pending = 0
        self._held = bytearray()
        self._stall_until_s = float("-inf")
        self._t0_s: float | None = None

    # --- run-time hooks -----------------------------------------------------------------------
    def corrupt_next(self, n_bytes: int = 1) -> None:
        """Corrupt the next ``n_bytes`` bytes sent."""
        with self._lock:
            self._corrupt_pending += n_bytes

    def drop_next(self, n_bytes: int = 1) -> None:
        """Drop the next ``n_bytes`` bytes sent."""
        with self._lock:
            self._drop_pending += n_bytes

    def set_silent(self, silent: bool) -> None:
        """Drop everything (``True``) until switched off again."""
        with self._lock:
            self.silent = silent

    def stall_for(self, duration_s: float, now_s: float) -> None:
        """Hold every byte from ``now_s`` for ``duration_s`` s, then release them as one burst."""
        with self._lock:
            self._stall_until_s = max(self._stall_until_s, now_s + duration_s)

    # --- the filter ---------------------------------------------------------------------------
    def process(self, data: bytes, now_s: float) -> bytes:
        """Return the bytes to write now for ``data`` sent at ``now_s`` s (held bytes excluded)."""
        with self._lock:
            out = self._release(now_s)
            if self.silent:
                self.counters.silenced += len(data)
                return bytes(out)
            damaged = self._damage(data)
            if self._stalled(now_s):
                self._held += damaged
                self.counters.stalled += len(damaged)
            else:
                out += damaged
            return bytes(out)

    def release(self, now_s: float) -> bytes:
        """Return the held bytes whose stall is over at ``now_s`` s (call periodically)."""
        with self._lock:
            return bytes(self._release(now_s))

    def _release(self, now_s: float) -> bytearray:
        if not self._held or self._stalled(now_s):
            return bytearray()
        burst, self._held = self._held, bytearray()
        self.counters.bursts += 1
        return burst

    def _stalled(self, now_s: float) -> bool:
        if now_s < self._stall_until_s:
            return True
        if self.stall_period_s <= 0 or self.stall_duration_s <= 0:
            return False
        if self._t0_s is None:
            self._t0_s = now_s
        phase = (now_s - self._t0_s) % self.stall_period_s
        # The stall sits at the end of each period so that a link starts out healthy.
        return phase >= self.stall_period_s - self.stall_duration_s

    def _damage(self, data: bytes) -> bytearray:
        out = bytearray()
        rng = self._rng
        for byte in data:
            if self._drop_pending > 0 or (
                self.drop_byte_prob and rng.random() < self.drop_byte_prob
            ):
                self._drop_pending = max(self._drop_pending - 1, 0)
                self.counters.dropped += 1
                continue
            if self._corrupt_pending > 0 or (
                self.corrupt_byte_prob and rng.random() < self.corrupt_byte_prob
            ):
                self._corrupt_pending = max(self._corrupt_pending - 1, 0)
                self.counters.corrupted += 1
                byte ^= rng.randrange(1, 256)
            out.append(byte)
        return out
