"""A time a loop of similar pieces of work must not run past.

A re-plan in the closed loop is of use only if it ends within its period; its work is a
sequence of short, similar pieces (the integrator's steps, the quadratic programme's
iterations). Checked before each piece, the loop stops where the next piece would end past the
deadline, judged by the time the piece before it took: the overrun is bounded by one piece's
jitter, whatever the machine's load.
"""

import math
import time

from .errors import PastDeadline


class Deadline:
    """A deadline ``at_s`` (``time.perf_counter`` s; ``inf``: none)."""

    def __init__(self, at_s: float = math.inf):
        self.at_s = float(at_s)
        self._last = None
        self._took = 0.0

    def begin(self) -> None:
        """A new loop starts: its first piece is judged by nothing before it (the work
        between two loops is not one of their pieces)."""
        self._last, self._took = None, 0.0

    def check(self) -> None:
        """Before a piece of work: raise :class:`.errors.PastDeadline` if it would end past the
        deadline, judged by the previous piece of this loop."""
        if self.at_s == math.inf:
            return
        now = time.perf_counter()
        if self._last is not None:
            self._took = now - self._last
        if now + self._took > self.at_s:
            raise PastDeadline(f"{now + self._took - self.at_s:.4f} s past the deadline")
        self._last = now


NONE = Deadline()
"""No deadline (never raises)."""
