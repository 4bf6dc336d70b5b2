"""Per-source bookkeeping: last sample time, time-out, accept/reject counters.

A source is *timed out* when no sample of it has been fused or tested for longer than its
``timeout_s``; the filter then runs on prediction for what that source observes and raises the
source's time-out bit in the status word. The bit clears with the next sample.
"""

from dataclasses import dataclass


@dataclass
class SourceMonitor:
    """Counters of one measurement source.

    Attributes
    ----------
    name : str
    timeout_s : float, s
    last_t_s : float or None, s
        Time of the last sample tested (None before the first).
    accepted, rejected, stale, timeouts : int
        Samples fused, samples rejected by the gate, samples too old to fuse, time-outs raised.
    out_of_order : int
        Samples older than the filter's time when they came (the stale ones among them).
    timed_out : bool
    """

    name: str
    timeout_s: float
    last_t_s: float | None = None
    accepted: int = 0
    rejected: int = 0
    stale: int = 0
    timeouts: int = 0
    out_of_order: int = 0
    timed_out: bool = False
    last_rejected: bool = False

    def record(self, t_s: float, accepted: bool) -> None:
        """A sample was tested at ``t_s``."""
        self.last_t_s = t_s
        self.timed_out = False
        self.last_rejected = not accepted
        if accepted:
            self.accepted += 1
        else:
            self.rejected += 1

    def heard(self, t_s: float) -> None:
        """A sample taken at ``t_s`` arrived and was left unfused (an estimator catching up
        with real time): the source is not silent."""
        self.last_t_s = t_s if self.last_t_s is None else max(self.last_t_s, t_s)
        self.timed_out = False

    def check(self, t_s: float, t_start_s: float) -> bool:
        """Update the time-out state at ``t_s``; True when it is newly timed out."""
        since = t_s - (t_start_s if self.last_t_s is None else self.last_t_s)
        if since > self.timeout_s and not self.timed_out:
            self.timed_out = True
            self.timeouts += 1
            return True
        return False

    def counters(self) -> dict:
        return {
            "accepted": self.accepted,
            "rejected": self.rejected,
            "stale": self.stale,
            "out_of_order": self.out_of_order,
            "timeouts": self.timeouts,
        }
