"""Byte-stream fault filter: each fault on explicit times, so nothing here depends on the clock."""

from gyrohost.simrig.config import StreamFaultConfig
from gyrohost.simrig.faults import FaultFilter

DATA = bytes(range(20))


def test_transparent_by_default():
    assert FaultFilter().process(DATA, 0.0) == DATA


def test_corrupt_next_changes_exactly_n_bytes():
    f = FaultFilter()
    f.corrupt_next(3)
    out = f.process(DATA, 0.0)
    assert len(out) == len(DATA)
    assert [i for i in range(len(DATA)) if out[i] != DATA[i]] == [0, 1, 2]
    assert f.process(DATA, 0.0) == DATA
    assert f.counters.corrupted == 3


def test_drop_next_removes_exactly_n_bytes():
    f = FaultFilter()
    f.drop_next(5)
    assert f.process(DATA, 0.0) == DATA[5:]
    assert f.counters.dropped == 5


def test_silence_until_switched_off():
    f = FaultFilter(StreamFaultConfig(silent=True))
    assert f.process(DATA, 0.0) == b""
    f.set_silent(False)
    assert f.process(DATA, 0.1) == DATA
    assert f.counters.silenced == len(DATA)


def test_run_time_stall_releases_one_burst_in_order():
    f = FaultFilter()
    f.stall_for(0.5, now_s=1.0)
    assert f.process(DATA[:10], 1.1) == b""
    assert f.process(DATA[10:], 1.2) == b""
    assert f.release(1.4) == b""
    assert f.release(1.5) == DATA
    assert f.counters.bursts == 1 and f.counters.stalled == len(DATA)


def test_periodic_stalls_hold_the_end_of_each_period():
    f = FaultFilter(StreamFaultConfig(stall_period_s=1.0, stall_duration_s=0.25))
    assert f.process(b"a", 0.0) == b"a"
    assert f.process(b"b", 0.8) == b""  # inside [0.75, 1.0)
    assert f.process(b"c", 1.1) == b"bc"  # burst, then the new byte
    assert f.process(b"d", 1.9) == b""


def test_probabilities_are_seeded_and_roughly_right():
    cfg = StreamFaultConfig(corrupt_byte_prob=0.1, drop_byte_prob=0.05, seed=7)
    a, b = FaultFilter(cfg), FaultFilter(cfg)
    data = bytes(10000)
    out = a.process(data, 0.0)
    assert out == b.process(data, 0.0)
    assert 400 < a.counters.dropped < 600
    assert 800 < a.counters.corrupted < 1100
    assert sum(1 for x in out if x) == a.counters.corrupted
