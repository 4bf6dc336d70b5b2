"""The collector kept out of the real-time loops: what exists at the start is frozen, garbage
from before is collected first, and the block's end gives the collector everything back."""

import gc
import weakref

from gyrohost.gcfreeze import heap_frozen


class _Node:
    pass


def _cycle():
    """A reference cycle nobody holds, and a weak reference to tell whether it still lives."""
    a, b = _Node(), _Node()
    a.other, b.other = b, a
    return weakref.ref(a)


def test_the_heap_is_frozen_inside_the_block_only_and_no_garbage_with_it():
    gc.unfreeze()
    dead = _cycle()
    with heap_frozen():
        assert dead() is None  # collected before the freeze, not kept for the block's life
        assert gc.get_freeze_count() > 1000
        young = _cycle()
        gc.collect()
        assert young() is None  # what the block allocates is still collected
    assert gc.get_freeze_count() == 0


def test_the_block_unfreezes_when_it_raises():
    try:
        with heap_frozen():
            raise RuntimeError("a fault in the loop")
    except RuntimeError:
        pass
    assert gc.get_freeze_count() == 0
