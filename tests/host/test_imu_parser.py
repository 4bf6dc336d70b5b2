"""BWT61CL parser against hand-built byte streams: conversions, every corruption case, resync."""

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from gyrohost.drivers.imu import (
    FRAME_LEN,
    Bwt61FrameParser,
    Bwt61Parser,
    FrameType,
    encode_frame,
)

G = 9.80665


def sample_bytes(accel=(0, 0, 2048), rate=(0, 0, 0), angle=(0, 0, 0), temp=0) -> bytes:
    return (
        encode_frame(0x51, (*accel, temp))
        + encode_frame(0x52, (*rate, temp))
        + encode_frame(0x53, (*angle, temp))
    )


def test_frame_layout_matches_the_datasheet():
    frame = encode_frame(0x51, (1, -1, 256, 0))
    assert frame[:2] == b"\x55\x51"
    assert frame[2:10] == bytes([1, 0, 0xFF, 0xFF, 0, 1, 0, 0])
    assert frame[10] == sum(frame[:10]) & 0xFF
    assert len(frame) == FRAME_LEN


def test_scales_convert_to_si():
    raw_temp = 340  # 1 degC above the offset
    stream = sample_bytes(
        (16384, -16384, 2048), (16384, 0, -32768), (16384, -8192, 32767), raw_temp
    )
    (s,) = Bwt61Parser().feed(stream, t_ns=123)
    np.testing.assert_allclose(s.accel_m_s2, [8 * G, -8 * G, G])
    np.testing.assert_allclose(s.omega_rad_s, np.deg2rad([1000.0, 0.0, -2000.0]))
    np.testing.assert_allclose(s.euler_rad, [math.pi / 2, -math.pi / 4, math.pi * 32767 / 32768])
    assert s.temperature_degC == pytest.approx(37.53)
    assert s.t_ns == 123


def test_byte_at_a_time_equals_all_at_once_and_stamps_arrival():
    stream = sample_bytes() * 3
    parser = Bwt61Parser()
    samples = []
    for i, byte in enumerate(stream):
        samples += parser.feed(bytes([byte]), t_ns=i)
    assert [s.t_ns for s in samples] == [32, 65, 98]  # index of each set's last byte
    assert parser.stats.samples == 3 and parser.stats.skipped_bytes == 0


def test_garbage_before_and_between_frames_is_skipped():
    junk = b"\x00\x55\x13\xff\x55"
    stream = junk + sample_bytes() + junk + sample_bytes()
    parser = Bwt61Parser()
    assert len(parser.feed(stream, 0)) == 2
    # Per junk: 0x55 0x13, then the 0x55 right before the frame's own 0x55 header.
    assert parser.stats.unknown_type == 4
    assert parser.stats.skipped_bytes == 2 * len(junk)


def test_bad_checksum_is_counted_and_the_set_dropped():
    bad = bytearray(sample_bytes())
    bad[10 + 11] ^= 0x01  # checksum of the rate frame
    parser = Bwt61Parser()
    assert parser.feed(bytes(bad) + sample_bytes(), 0) != []
    assert parser.stats.corrupt_frames == 1
    assert parser.stats.dropped_frames == 1
    assert parser.stats.samples == 1


def test_corrupt_payload_byte_is_caught_by_the_checksum():
    bad = bytearray(sample_bytes())
    bad[3] ^= 0x40
    parser = Bwt61Parser()
    assert parser.feed(bytes(bad), 0) == []
    assert parser.stats.corrupt_frames == 1


def test_truncated_frame_then_a_good_one_resyncs():
    stream = sample_bytes()[:7] + sample_bytes()
    parser = Bwt61Parser()
    samples = parser.feed(stream, 0)
    assert len(samples) == 1
    assert parser.stats.frames == 3


def test_unknown_type_is_skipped():
    frame = encode_frame(0x54, (1, 2, 3, 4))  # a valid checksum but not a BWT61CL type
    parser = Bwt61Parser()
    assert len(parser.feed(frame + sample_bytes(), 0)) == 1
    assert parser.stats.unknown_type == 1


def test_a_partial_frame_waits_for_more_bytes():
    stream = sample_bytes()
    parser = Bwt61Parser()
    assert parser.feed(stream[:-1], 0) == []
    assert len(parser.feed(stream[-1:], 1)) == 1


@pytest.mark.parametrize(
    ("order", "dropped", "samples"),
    [
        ([0x51, 0x52, 0x53, 0x51, 0x52, 0x53], 0, 2),
        ([0x51, 0x53, 0x51, 0x52, 0x53], 1, 1),  # rate frame lost
        ([0x51, 0x52, 0x53, 0x52, 0x53, 0x51, 0x52, 0x53], 1, 2),  # accel frame lost
        ([0x51, 0x51, 0x52, 0x53], 2, 1),  # rate and angle lost
        ([0x52, 0x53, 0x51, 0x52, 0x53], 0, 1),  # start mid-set: only synchronises
    ],
)
def test_missing_frames_are_counted_once(order, dropped, samples):
    parser = Bwt61Parser()
    out = parser.feed(b"".join(encode_frame(t, (0, 0, 0, 0)) for t in order), 0)
    assert (parser.stats.dropped_frames, len(out)) == (dropped, samples)


# --- property-based -----------------------------------------------------------------------------

frame_strategy = st.builds(
    lambda t, v: encode_frame(t, v),
    st.sampled_from([int(t) for t in FrameType]),
    st.tuples(*[st.integers(-32768, 32767)] * 4),
)
garbage_strategy = st.one_of(
    st.binary(max_size=30),
    frame_strategy.map(lambda f: f[: len(f) // 2]),  # truncated frame
    frame_strategy.map(lambda f: f[:10] + bytes([(f[10] + 1) & 0xFF])),  # bad checksum
    st.just(b"\x55"),
    st.just(b"\x55\x55\x51"),
)


def false_frame_starts(stream: bytes, true_starts: set[int]) -> bool:
    """True if some position that is not an embedded frame looks like a complete valid frame."""
    for i in range(len(stream) - FRAME_LEN + 1):
        if i in true_starts or stream[i] != 0x55 or stream[i + 1] not in (0x51, 0x52, 0x53):
            continue
        if stream[i + 10] == sum(stream[i : i + 10]) & 0xFF:
            return True
    return False


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.tuples(garbage_strategy, frame_strategy), max_size=12),
    st.binary(max_size=20),
    st.lists(st.integers(1, 40), min_size=1, max_size=20),
)
def test_every_embedded_frame_is_recovered(pieces, tail, chunk_sizes):
    stream = bytearray()
    starts = []
    for garbage, frame in pieces:
        stream += garbage
        starts.append(len(stream))
        stream += frame
    stream += tail
    # A frame-shaped accident in the garbage would be a frame by any definition: exclude it.
    assume(not false_frame_starts(bytes(stream), set(starts)))
    parser = Bwt61FrameParser()
    frames, pos, k = [], 0, 0
    while pos < len(stream):  # arbitrary chunking: the parser is incremental
        size = chunk_sizes[k % len(chunk_sizes)]
        frames += parser.feed(bytes(stream[pos : pos + size]), t_ns=pos)
        pos, k = pos + size, k + 1
    assert [f.encode() for f in frames] == [frame for _, frame in pieces]


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=400))
def test_random_bytes_never_raise(data):
    parser = Bwt61Parser()
    parser.feed(data, 0)
    stats = parser.stats
    assert stats.bytes_in == len(data)
    assert stats.frames * FRAME_LEN + stats.skipped_bytes <= len(data)


def test_garbage_counts_as_skipped_bytes_and_describes_itself():
    p = Bwt61Parser()
    assert len(p.feed(sample_bytes(), t_ns=0)) == 1
    before = p.stats.copy()
    garbage = bytes([0x00, 0x55, 0x99] * 200) + encode_frame(0x52, (1, 2, 3, 4))[:10] + b"\x00"
    assert p.feed(garbage, t_ns=1) == []
    seen = p.stats.since(before)
    assert seen.bytes_in == len(garbage)
    assert seen.frames == 0 and seen.samples == 0
    assert seen.unknown_type == 200 and seen.corrupt_frames == 1
    assert seen.skipped_bytes == len(garbage)
    assert seen.describe() == (
        f"{len(garbage)} bytes in, skipped {len(garbage)} bytes, 0 frames "
        "(1 bad checksums, 200 unknown types, 0 dropped), 0 samples"
    )
