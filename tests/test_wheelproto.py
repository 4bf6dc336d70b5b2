"""Wheel-board codec: the Python tables equal the firmware's .def tables; framing by hand."""

import re
import struct
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from protocol_reference import crc_bytewise

from gyrohost.drivers import wheelproto as wp

FW = Path(__file__).resolve().parents[1] / "firmware" / "lib"
C_STRING = r'"((?:[^"\\]|\\.)*)"'


def def_rows(path: Path, macro: str) -> list[list[str]]:
    """Rows of X-macro invocations ``macro(a, b, "c", ...)`` in a .def file, as strings."""
    rows = []
    for line in path.read_text().splitlines():
        m = re.match(rf"\s*{macro}\((.*)\)\s*$", line)
        if m is None:
            continue
        args = re.findall(rf"{C_STRING}|([^,\s][^,]*?)\s*(?=,|$)", m.group(1))
        rows.append([s if s or not o else o for s, o in args])
    return rows


def test_message_table_matches_firmware():
    rows = def_rows(FW / "wheel_proto" / "proto_messages.def", "PROTO_MSG")
    fw = {(n, int(i, 0), d, int(ln), f, tuple(fl.split())) for n, i, d, ln, f, fl in rows}
    py = {(m.name, m.id, m.direction, m.size, m.fmt, m.fields) for m in wp.MESSAGES}
    assert fw == py, f"only firmware: {fw - py}; only host: {py - fw}"


@pytest.mark.parametrize(
    ("macro", "table"),
    [
        ("PROTO_FAULT", wp.FAULTS),
        ("PROTO_STATUS", wp.STATUS),
        ("PROTO_ERROR", wp.ERRORS),
        ("PROTO_CAL", wp.CAL_FAILURES),
    ],
)
def test_code_tables_match_firmware(macro, table):
    rows = def_rows(FW / "wheel_proto" / "proto_codes.def", macro)
    fw = {int(num): (name, text) for name, num, text in rows}
    assert fw == table


def test_param_table_matches_firmware():
    rows = def_rows(FW / "wheel_params" / "params.def", "PRM")
    fw = {(n, int(i), int(d), int(lo), int(hi), u) for n, i, d, lo, hi, u, _ in rows}
    py = {(p.name, p.id, p.default, p.min, p.max, p.unit) for p in wp.PARAMS}
    assert fw == py, f"only firmware: {fw - py}; only host: {py - fw}"
    prm_h = (FW / "wheel_params" / "params.h").read_text()
    assert int(re.search(r"#define PRM_COUNT (\d+)", prm_h).group(1)) == len(wp.PARAMS)


def test_versions_and_sizes_match_firmware():
    ver = (FW / "wheel_proto" / "proto_version.h").read_text()
    assert int(re.search(r"#define PROTO_VERSION (\d+)", ver).group(1)) == wp.PROTO_VERSION
    proto_h = (FW / "wheel_proto" / "proto.h").read_text()
    assert int(re.search(r"#define PROTO_MAX_PAYLOAD (\d+)", proto_h).group(1)) == wp.MAX_PAYLOAD


def test_crc_check_value_and_reference():
    assert wp.crc16(b"123456789") == 0x29B1
    for data in (b"", b"\x00", b"\xff" * 40, bytes(range(43))):
        assert wp.crc16(data) == crc_bytewise(data)


def test_cobs_known_vectors():
    assert wp.cobs_encode(b"\x00") == b"\x01\x01"
    assert wp.cobs_encode(b"\x11\x22\x00\x33") == b"\x03\x11\x22\x02\x33"
    assert wp.cobs_encode(b"") == b"\x01"
    assert wp.cobs_decode(b"\x03\x11\x22\x02\x33") == b"\x11\x22\x00\x33"


@given(st.binary(max_size=253))
def test_cobs_round_trip(data):
    enc = wp.cobs_encode(data)
    assert 0 not in enc
    assert wp.cobs_decode(enc) == data


def test_hand_built_hello_frame():
    # HELLO: id 0x01, no payload, CRC of b"\x01" little-endian, then COBS and the delimiter.
    crc = crc_bytewise(b"\x01")
    raw = bytes([0x01, crc & 0xFF, crc >> 8])
    assert 0 not in raw
    assert wp.encode("HELLO") == bytes([4]) + raw + b"\x00"


@given(
    st.sampled_from(wp.MESSAGES).flatmap(
        lambda m: st.tuples(st.just(m), st.binary(min_size=m.size, max_size=m.size))
    )
)
def test_every_message_round_trips(case):
    spec, payload = case
    fields = dict(zip(spec.fields, struct.unpack(spec.fmt, payload), strict=True))
    wire = wp.encode(spec.name, **fields)
    assert wire.endswith(b"\x00") and 0 not in wire[:-1]
    (msg,) = wp.FrameDecoder().feed(wire)
    assert (msg.name, msg.fields) == (spec.name, fields)


def frame_of(raw: bytes) -> bytes:
    return wp.cobs_encode(raw) + b"\x00"


def with_crc(body: bytes) -> bytes:
    return body + struct.pack("<H", crc_bytewise(body))


@pytest.mark.parametrize(
    ("wire", "kind"),
    [
        (frame_of(b"\x05\x01\x00\x00"), "bad_crc"),
        (frame_of(b"\x01\x02"), "short"),
        (b"\x33" * 60 + b"\x00", "oversize"),
        (b"\x09\x01\x02\x00", "bad_cobs"),
        (frame_of(with_crc(b"\x55\x01")), "unknown_id"),
        (frame_of(with_crc(b"\x03\x01\x02")), "bad_length"),
    ],
)
def test_corrupt_frames_counted_and_dropped(wire, kind):
    dec = wp.FrameDecoder()
    good = wp.encode("HEARTBEAT")
    msgs = dec.feed(good + wire + good)
    assert [m.name for m in msgs] == ["HEARTBEAT", "HEARTBEAT"]
    assert dec.dropped == {kind: 1}
    assert isinstance(dec.last_error, ValueError)


def test_encode_errors_name_the_problem():
    with pytest.raises(wp.ProtocolError, match="unknown message name 'NOPE'"):
        wp.encode("NOPE")
    with pytest.raises(wp.ProtocolError, match="missing fields"):
        wp.encode("PARAM_GET")
    with pytest.raises(wp.ProtocolError, match="out of range"):
        wp.encode("PARAM_GET", param_id=300)


def test_code_texts_and_telemetry_units():
    assert wp.fault_names(0b1_0000_0011) == ["HEARTBEAT_LOST", "ENCODER_M0", "RX_OVERFLOW"]
    assert wp.error_name(3) == "SETPOINT_ABOVE_MAX"
    assert "unknown" in wp.error_text(99)
    fields = dict.fromkeys(wp.BY_NAME["TELEMETRY"].fields, 0)
    fields.update(w0_mrad_s=74870, d1_q15=-32767, faults=1, status=0b101)
    (msg,) = wp.FrameDecoder().feed(wp.encode("TELEMETRY", **fields))
    tel = wp.Telemetry.from_message(msg)
    assert tel.omega_rad_s[0] == pytest.approx(74.87)
    assert tel.drive[1] == -1.0
    assert tel.fault_names == ["HEARTBEAT_LOST"]
    assert tel.status_names == ["OUTPUTS_ENABLED", "FAILSAFE"]
