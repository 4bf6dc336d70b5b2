"""The garbage collector kept out of the real-time loops.

CPython's full collection scans every tracked object. A run's process holds some 10^5 of them
(models, drivers, logs), and a full collection in the middle of a run took 23 to 59 ms. In the
run loop that held the 100 Hz ticks for up to six periods: no servo goals for 64 ms, then the
servos ran to the next goal at their speed limit (docs/run.md). Objects that exist when a loop
starts live as long as it does, so they are frozen: collections then scan only what the loop
allocated since.

The collection before the freeze holds the interpreter for its whole length (0.1 s in a run's
process, half a second in a test session's): a block is entered before any device thread
starts, or the wheel board's heartbeat waits that long and the board latches its fail-safe.
"""

import gc
from contextlib import contextmanager


@contextmanager
def heap_frozen():
    """Within the block, the objects that existed at its start are out of the collector's
    scans (collected once first, so that no garbage is frozen with them)."""
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()
