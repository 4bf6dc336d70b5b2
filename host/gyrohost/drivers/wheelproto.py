"""Pure codec of the wheel-board protocol (docs/protocol.md): COBS, CRC-16, messages, code texts.

Wire frame: ``COBS(id | payload | crc16_le) 0x00``; CRC-16/CCITT-FALSE over id and payload; all
fields little-endian. The tables below follow ``firmware/lib/wheel_proto/proto_messages.def``,
``proto_codes.def`` and ``firmware/lib/wheel_params/params.def``; tests/test_wheelproto.py parses
those files and fails on any difference. Numbers travel on the wire, texts live here.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

from .errors import FrameError, ProtocolError

PROTO_VERSION = 4
MAX_PAYLOAD = 40
MAX_RAW = 1 + MAX_PAYLOAD + 2
MAX_ENCODED = MAX_RAW + 1
N_WHEELS = 4
TICK_HZ = 1000


@dataclass(frozen=True)
class MessageSpec:
    name: str
    id: int
    direction: str  # "H2D" host to device, "D2H" device to host
    fmt: str  # struct format of the payload
    fields: tuple[str, ...]

    @property
    def size(self) -> int:
        return struct.calcsize(self.fmt)


def _msg(name: str, mid: int, direction: str, fmt: str, fields: str) -> MessageSpec:
    return MessageSpec(name, mid, direction, fmt, tuple(fields.split()))


MESSAGES: tuple[MessageSpec, ...] = (
    _msg("HELLO", 0x01, "H2D", "<", ""),
    _msg("HEARTBEAT", 0x02, "H2D", "<", ""),
    _msg("SET_SPEEDS", 0x03, "H2D", "<iiii", "w0_mrad_s w1_mrad_s w2_mrad_s w3_mrad_s"),
    _msg("STOP_ALL", 0x04, "H2D", "<", ""),
    _msg("PARAM_GET", 0x05, "H2D", "<B", "param_id"),
    _msg("PARAM_SET", 0x06, "H2D", "<Bi", "param_id value"),
    _msg("PARAM_SAVE", 0x07, "H2D", "<", ""),
    _msg("PARAM_DEFAULTS", 0x08, "H2D", "<", ""),
    _msg("CLEAR_FAULTS", 0x09, "H2D", "<H", "mask"),
    _msg("GET_STATS", 0x0A, "H2D", "<", ""),
    _msg("CALIBRATE_ENC", 0x0B, "H2D", "<B", "wheel"),
    _msg(
        "HELLO_REPLY",
        0x81,
        "D2H",
        "<BBBBBH",
        "proto_version fw_major fw_minor n_wheels n_params tick_hz",
    ),
    _msg(
        "TELEMETRY",
        0x82,
        "D2H",
        "<IHiiiihhhhBH",
        "t_us seq w0_mrad_s w1_mrad_s w2_mrad_s w3_mrad_s "
        "d0_q15 d1_q15 d2_q15 d3_q15 status faults",
    ),
    _msg("ACK", 0x83, "D2H", "<B", "req_id"),
    _msg("ERROR", 0x84, "D2H", "<BBB", "req_id code detail"),
    _msg("PARAM_VALUE", 0x85, "D2H", "<Bi", "param_id value"),
    _msg(
        "STATS",
        0x86,
        "D2H",
        "<HHHHHHHHHH",
        "bad_crc short oversize bad_cobs unknown_id bad_length tx_dropped tick_overruns "
        "rx_overflow step_max_us",
    ),
)
BY_NAME = {m.name: m for m in MESSAGES}
BY_ID = {m.id: m for m in MESSAGES}

# bit -> (name, text): latched fault word of TELEMETRY.
FAULTS: dict[int, tuple[str, str]] = {
    0: (
        "HEARTBEAT_LOST",
        "no control frame (HEARTBEAT, SET_SPEEDS, STOP_ALL) from the host within HEARTBEAT_MS: "
        "all wheels ramped to zero",
    ),
    **{
        1 + w: (
            f"ENCODER_M{w}",
            f"encoder of wheel {w} faulted (bad words; ENC_STUCK or ENC_DIAG when set name "
            f"the cause): wheel {w} disabled",
        )
        for w in range(4)
    },
    5: ("TICK_OVERRUN", "a 1 ms control tick was missed"),
    6: ("PARAMS_DEFAULTED", "EEPROM parameter image invalid at boot: defaults in use"),
    7: (
        "WATCHDOG_RESET",
        "the last reset was caused by the watchdog (a hang; behind the stock bootloader only a "
        "hang with interrupts on is seen)",
    ),
    8: ("RX_OVERFLOW", "UART receive buffer overflowed: bytes were lost"),
    9: (
        "ENC_STUCK",
        "an encoder read 0x0000 or 0x3FFF unchanged (MISO stuck low or high) while its wheel "
        "was driven at half DRIVE_MAX or more: the ENCODER_Mw bit names the wheel",
    ),
    10: (
        "ENC_DIAG",
        "an encoder's diagnostics register reported offset compensation unfinished, CORDIC "
        "overflow or a magnet too strong or too weak: the ENCODER_Mw bit names the wheel",
    ),
    11: (
        "STALL",
        "a wheel's drive was saturated with its speed below STALL_SPEED for MOTION_FAULT_MS: "
        "all wheels disabled",
    ),
    12: (
        "RUNAWAY",
        "a wheel turned against its setpoint or above SPEED_MAX by more than RUNAWAY_MARGIN for "
        "MOTION_FAULT_MS (a wrong ENC_OFFSET?): all wheels disabled",
    ),
    13: (
        "BROWN_OUT_RESET",
        "the last reset was a brown-out (supply below the BOD level; seen only where no "
        "bootloader cleared MCUSR)",
    ),
    14: (
        "OPEN_LOOP_LIMIT",
        "open loop (MODE 1) drove a wheel for 10 s without a stop: all wheels ramped to zero",
    ),
}
# Faults that make the device refuse setpoints until CLEAR_FAULTS (ENC_STUCK and ENC_DIAG come
# with the ENCODER_Mw bit of their wheel).
BLOCKING_FAULTS = frozenset(
    {
        "HEARTBEAT_LOST",
        "ENCODER_M0",
        "ENCODER_M1",
        "ENCODER_M2",
        "ENCODER_M3",
        "STALL",
        "RUNAWAY",
        "OPEN_LOOP_LIMIT",
    }
)

# bit -> (name, text): live status byte of TELEMETRY.
STATUS: dict[int, tuple[str, str]] = {
    0: ("OUTPUTS_ENABLED", "at least one driver stage is enabled"),
    1: ("OPEN_LOOP", "open-loop mode (no encoders): speeds are the commanded ones"),
    2: ("FAILSAFE", "fail-safe active: setpoints forced to zero"),
    3: ("SAVING", "parameter save to EEPROM in progress"),
    **{
        4 + w: (f"SATURATED_M{w}", f"wheel {w} drive held by the output or slew limit")
        for w in range(4)
    },
}

# code -> (name, text): ERROR reply codes.
ERRORS: dict[int, tuple[str, str]] = {
    1: ("UNKNOWN_MESSAGE", "unknown message id (detail: the id)"),
    2: (
        "BAD_LENGTH",
        "payload length does not match the message table (detail: received length)",
    ),
    3: (
        "SETPOINT_ABOVE_MAX",
        "speed setpoint above the configured maximum (detail: wheel index)",
    ),
    4: ("UNKNOWN_PARAM", "unknown parameter id (detail: the id)"),
    5: ("PARAM_OUT_OF_RANGE", "parameter value outside its range (detail: the id)"),
    6: (
        "FAULT_ACTIVE",
        "setpoints refused while a blocking fault is latched: send CLEAR_FAULTS",
    ),
    7: (
        "BUSY",
        "not possible now: outputs enabled (mode, pole pairs, calibration), open loop "
        "(calibration) or a save or calibration in progress",
    ),
    8: (
        "OFFSET_UNCALIBRATED",
        "closed-loop setpoint refused: the wheel's ENC_OFFSET is a default; run CALIBRATE_ENC "
        "or set it (detail: wheel index)",
    ),
    9: ("CALIBRATION_FAILED", "CALIBRATE_ENC failed (detail: the reason)"),
}

# detail -> (name, text): reasons of a CALIBRATION_FAILED error.
CAL_FAILURES: dict[int, tuple[str, str]] = {
    1: (
        "NOT_MOVED",
        "the rotor did not follow the turning field: motor, driver stage or encoder not "
        "connected, or OPEN_LOOP_DRIVE too low",
    ),
    2: (
        "POLE_PAIRS",
        "the rotor moved by an angle that does not match POLE_PAIRS, or did not come back",
    ),
    3: (
        "REVERSED",
        "the encoder counts down while the field turns forwards: swap two motor phases",
    ),
    4: ("ENCODER", "an encoder fault latched during the calibration"),
    5: ("INTERRUPTED", "interrupted by STOP_ALL or the heartbeat fail-safe"),
    6: ("BAD_WHEEL", "no such wheel (0..3)"),
}


@dataclass(frozen=True)
class ParamSpec:
    name: str
    id: int
    default: int
    min: int
    max: int
    unit: str


def _p(name: str, pid: int, default: int, lo: int, hi: int, unit: str) -> ParamSpec:
    return ParamSpec(name, pid, default, lo, hi, unit)


PARAMS: tuple[ParamSpec, ...] = (
    _p("MODE", 0, 0, 0, 1, "-"),
    _p("POLE_PAIRS", 1, 7, 1, 40, "-"),
    _p("KP", 2, 120, 0, 65535, "Q15/(count/tick)"),
    _p("KI", 3, 3, 0, 65535, "Q15/(count/tick)/tick"),
    _p("DRIVE_MAX_Q15", 4, 16384, 0, 32767, "Q15"),
    _p("SLEW_Q15", 5, 1000, 1, 32767, "Q15/tick"),
    _p("SPEED_MAX_MRAD_S", 6, 157080, 0, 400000, "mrad/s"),
    _p("ACCEL_RAD_S2", 7, 100, 1, 10000, "rad/s^2"),
    _p("DECEL_RAD_S2", 8, 200, 50, 10000, "rad/s^2"),
    _p("HEARTBEAT_MS", 9, 250, 20, 1000, "ms"),
    _p("TELEMETRY_DIV", 10, 2, 0, 100, "ticks"),
    _p("SPEED_FILTER_SHIFT", 11, 3, 0, 8, "-"),
    _p("OPEN_LOOP_DRIVE_Q15", 12, 6000, 0, 16384, "Q15"),
    _p("LEAD_Q8", 13, 128, 0, 512, "tick/256"),
    _p("ENC_FAULT_LIMIT", 14, 5, 1, 255, "ticks"),
    *(_p(f"ENC_OFFSET_M{w}", 15 + w, 0, 0, 65535, "turn/65536") for w in range(4)),
    _p("MOTION_FAULT_MS", 19, 50, 1, 200, "ms"),
    _p("STALL_SPEED_MRAD_S", 20, 2000, 1000, 100000, "mrad/s"),
    _p("RUNAWAY_MARGIN_MRAD_S", 21, 10000, 0, 50000, "mrad/s"),
)
PARAM_BY_NAME = {p.name: p for p in PARAMS}
PARAM_BY_ID = {p.id: p for p in PARAMS}


def _crc16_table() -> tuple[int, ...]:
    """The 256 CRC-16/CCITT remainders of a byte in the high position (poly 0x1021)."""
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


_CRC16_TABLE = _crc16_table()


def crc16(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF); ``crc16(b"123456789") == 0x29B1``.

    Table-driven, one lookup per byte: the host decodes (and the rig encodes) 500 telemetry
    frames per second.
    """
    for byte in data:
        crc = ((crc << 8) & 0xFFFF) ^ _CRC16_TABLE[(crc >> 8) ^ byte]
    return crc


def cobs_encode(raw: bytes) -> bytes:
    """COBS-encode ``raw`` (at most 253 bytes, so no 0xFF code) without the 0x00 delimiter."""
    if len(raw) > 253:
        raise ProtocolError(f"COBS input of {len(raw)} bytes: frames are at most 253 bytes")
    out = bytearray()
    for block in raw.split(b"\x00"):
        out.append(len(block) + 1)
        out += block
    return bytes(out)


def cobs_decode(enc: bytes) -> bytes:
    """Decode one COBS block sequence (no delimiter); raises FrameError("bad_cobs")."""
    out = bytearray()
    i = 0
    while i < len(enc):
        code = enc[i]
        if code == 0 or i + code > len(enc):
            raise FrameError("bad_cobs", f"code {code:#04x} at byte {i} of {len(enc)}")
        run = enc[i + 1 : i + code]
        if 0 in run:
            raise FrameError("bad_cobs", f"zero byte inside the run starting at byte {i}")
        out += run
        i += code
        if code != 0xFF and i < len(enc):
            out.append(0)
    return bytes(out)


def encode(name: str, **fields: int) -> bytes:
    """Wire bytes (COBS + 0x00) of message ``name`` with integer ``fields``."""
    spec = BY_NAME.get(name)
    if spec is None:
        raise ProtocolError(f"unknown message name {name!r}")
    missing = set(spec.fields) - set(fields)
    extra = set(fields) - set(spec.fields)
    if missing or extra:
        raise ProtocolError(
            f"message {name}: missing fields {sorted(missing)}, unknown fields {sorted(extra)}"
        )
    try:
        payload = struct.pack(spec.fmt, *(fields[f] for f in spec.fields))
    except struct.error as exc:
        raise ProtocolError(f"message {name}: field value out of range: {exc}") from None
    return encode_raw(spec.id, payload)


def wire_time_s(name: str, baud: int) -> float:
    """Time the frame of message ``name`` takes on the wire at ``baud``, s: its id, payload
    and CRC, COBS's one code byte (a frame under 254 bytes) and the delimiter, 10 bits a byte
    (8N1)."""
    return (1 + BY_NAME[name].size + 2 + 2) * 10.0 / baud


def encode_raw(msg_id: int, payload: bytes) -> bytes:
    """Wire bytes of an arbitrary id and payload (tests use it to build bad frames)."""
    if len(payload) > MAX_PAYLOAD:
        raise ProtocolError(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD}")
    raw = bytes([msg_id]) + payload
    raw += struct.pack("<H", crc16(raw))
    return cobs_encode(raw) + b"\x00"


@dataclass(frozen=True)
class Message:
    name: str
    id: int
    fields: dict[str, Any]


def decode_frame(enc: bytes) -> Message:
    """Decode one encoded frame (bytes between two delimiters); raises FrameError."""
    if len(enc) > MAX_ENCODED:
        raise FrameError("oversize", f"{len(enc)} encoded bytes, at most {MAX_ENCODED}")
    raw = cobs_decode(enc)
    if len(raw) < 3:
        raise FrameError("short", f"{len(raw)} decoded bytes, need id + 2 CRC bytes")
    body, (crc,) = raw[:-2], struct.unpack("<H", raw[-2:])
    if crc16(body) != crc:
        raise FrameError("bad_crc", f"CRC {crc:#06x} received, {crc16(body):#06x} computed")
    spec = BY_ID.get(body[0])
    if spec is None:
        raise FrameError("unknown_id", f"message id {body[0]:#04x}")
    payload = body[1:]
    if len(payload) != spec.size:
        raise FrameError(
            "bad_length", f"{spec.name}: {len(payload)} payload bytes, expected {spec.size}"
        )
    return Message(
        spec.name, spec.id, dict(zip(spec.fields, struct.unpack(spec.fmt, payload), strict=True))
    )


class FrameDecoder:
    """Incremental receiver: feed bytes, get messages; dropped frames are counted by kind."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self._overflow = False
        self.dropped: dict[str, int] = {}
        self.last_error: FrameError | None = None

    def feed(self, data: bytes) -> list[Message]:
        out: list[Message] = []
        for b in data:
            if b != 0:
                if len(self._buf) < MAX_ENCODED:
                    self._buf.append(b)
                else:
                    self._overflow = True
                continue
            msg = self._finish()
            if msg is not None:
                out.append(msg)
        return out

    def _finish(self) -> Message | None:
        enc, overflow = bytes(self._buf), self._overflow
        self._buf.clear()
        self._overflow = False
        if not enc and not overflow:
            return None
        try:
            if overflow:
                raise FrameError("oversize", f"more than {MAX_ENCODED} bytes before 0x00")
            return decode_frame(enc)
        except FrameError as exc:
            self.dropped[exc.kind] = self.dropped.get(exc.kind, 0) + 1
            self.last_error = exc
            return None


def bit_names(word: int, table: dict[int, tuple[str, str]]) -> list[str]:
    """Names of the set bits of ``word``; unknown bits as ``BIT<n>``."""
    names = []
    for bit in range(16):
        if word >> bit & 1:
            names.append(table[bit][0] if bit in table else f"BIT{bit}")
    return names


def fault_names(faults: int) -> list[str]:
    return bit_names(faults, FAULTS)


def fault_mask(names: list[str] | tuple[str, ...] | frozenset[str]) -> int:
    """The fault word with the bits of ``names`` set; raises ProtocolError on an unknown name."""
    bits = {name: bit for bit, (name, _) in FAULTS.items()}
    unknown = sorted(set(names) - set(bits))
    if unknown:
        raise ProtocolError(f"unknown wheel-board fault names {unknown}; known: {sorted(bits)}")
    return sum(1 << bits[n] for n in set(names))


def fault_text(name: str) -> str:
    """The text of a fault name (``BIT<n>`` for bits this host does not know)."""
    return next((t for n, t in FAULTS.values() if n == name), "unknown fault bit")


def cal_failure(detail: int) -> tuple[str, str]:
    """(name, text) of a CALIBRATION_FAILED detail."""
    return CAL_FAILURES.get(detail, (f"CAL_{detail}", f"unknown calibration failure {detail}"))


def status_names(status: int) -> list[str]:
    return bit_names(status, STATUS)


def error_name(code: int) -> str:
    return ERRORS[code][0] if code in ERRORS else f"ERROR_{code}"


def error_text(code: int) -> str:
    return ERRORS[code][1] if code in ERRORS else f"unknown error code {code}"


ERROR_FIXES = {"OFFSET_UNCALIBRATED": "gyrotens wheels calibrate --wheel {detail}"}
"""Error name -> the command that lifts it (the texts above are the firmware's own)."""


def error_fix(code: int, detail: int) -> str:
    """The command that lifts error ``code`` for ``detail``; ``""`` when none does."""
    return ERROR_FIXES.get(error_name(code), "").format(detail=detail)


@dataclass(frozen=True)
class Telemetry:
    """One TELEMETRY message in SI units.

    t_us : device time stamp of the control step, us (wraps at 2**32)
    omega_rad_s : tuple of 4 wheel speeds, rad/s
    drive : tuple of 4 signed drive levels, fraction of the supply (-1..1)
    """

    t_us: int
    seq: int
    omega_rad_s: tuple[float, float, float, float]
    drive: tuple[float, float, float, float]
    status: int
    faults: int

    @classmethod
    def from_message(cls, msg: Message) -> Telemetry:
        f = msg.fields
        return cls(
            t_us=f["t_us"],
            seq=f["seq"],
            omega_rad_s=tuple(f[f"w{i}_mrad_s"] / 1000.0 for i in range(4)),
            drive=tuple(f[f"d{i}_q15"] / 32767.0 for i in range(4)),
            status=f["status"],
            faults=f["faults"],
        )

    @property
    def fault_names(self) -> list[str]:
        return fault_names(self.faults)

    @property
    def status_names(self) -> list[str]:
        return status_names(self.status)
