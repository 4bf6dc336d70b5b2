"""WitMotion BWT61CL (MPU6050 inside) driver: frame parser, sample assembly, serial port I/O.

Wire format (field notes section 4): 11-byte frames ``0x55, type, x, y, z, T, checksum`` with
little-endian int16 ``x, y, z, T`` and ``checksum`` the low byte of the sum of the first 10 bytes.
Types: ``0x51`` acceleration (raw/32768*16 g), ``0x52`` angular rate (raw/32768*2000 deg/s),
``0x53`` Z-Y-X Euler angles roll, pitch, yaw (raw/32768*180 deg); ``T`` is raw/340 + 36.53 degC.
The device sends 0x51, 0x52, 0x53 in that order once per output period.

Layers, each usable alone:

- :class:`Bwt61FrameParser` -- bytes in, checked :class:`ImuFrame` out; resynchronises on the next
  ``0x55`` after garbage, a bad checksum or an unknown type; never raises on any input.
- :class:`Bwt61SampleAssembler` -- frames in, one :class:`ImuSample` per complete 0x51/0x52/0x53 set
  out; counts the frames missing from the sequence as dropped.
- :class:`Bwt61Parser` -- both of the above (what the driver uses, what tests feed hand-built
  streams to).
- :class:`Bwt61Driver` -- the serial port (any path, a pty included), time stamps on arrival and the
  configuration commands ``FF AA xx``.
"""

import struct
import time
from dataclasses import dataclass, field, fields, replace
from enum import IntEnum

import numpy as np
import serial

from .errors import ImuConfigError, ImuError, ImuTimeoutError
from .portlock import LockedSerial

FRAME_LEN = 11
HEADER = 0x55
STANDARD_GRAVITY_M_S2 = 9.80665
ACCEL_SCALE_M_S2 = 16.0 * STANDARD_GRAVITY_M_S2 / 32768.0
"""Acceleration per raw count, m/s^2 (full scale 16 g)."""
RATE_SCALE_RAD_S = np.deg2rad(2000.0) / 32768.0
"""Angular rate per raw count, rad/s (full scale 2000 deg/s)."""
ANGLE_SCALE_RAD = np.pi / 32768.0
"""Angle per raw count, rad (full scale 180 deg)."""
TEMP_SCALE_DEGC = 1.0 / 340.0
TEMP_OFFSET_DEGC = 36.53

_INT16X4 = struct.Struct("<4h")


class FrameType(IntEnum):
    """BWT61CL output frame types."""

    ACCEL = 0x51
    RATE = 0x52
    ANGLE = 0x53


class Command(bytes):
    """A BWT61CL configuration command (``FF AA xx``)."""


ZERO_YAW = Command(b"\xff\xaa\x52")
CALIBRATE_ACCEL = Command(b"\xff\xaa\x67")
RATE_115200_100HZ = Command(b"\xff\xaa\x63")
RATE_9600_20HZ = Command(b"\xff\xaa\x64")
MOUNT_HORIZONTAL = Command(b"\xff\xaa\x65")
MOUNT_VERTICAL = Command(b"\xff\xaa\x66")

RATE_COMMANDS = {100: (RATE_115200_100HZ, 115200), 20: (RATE_9600_20HZ, 9600)}
"""Output rate, Hz -> (command, baud rate the device switches to)."""


def frame_checksum(first10: bytes) -> int:
    """Checksum of a frame: low byte of the sum of its first 10 bytes."""
    return sum(first10[:10]) & 0xFF


def encode_frame(frame_type: int, values: tuple[int, int, int, int]) -> bytes:
    """Build one 11-byte frame from four raw int16 ``values`` (x, y, z, temperature)."""
    body = bytes((HEADER, frame_type)) + _INT16X4.pack(*values)
    return body + bytes((frame_checksum(body),))


@dataclass(frozen=True)
class ImuFrame:
    """One checked frame: ``raw`` = (x, y, z, T) int16 counts; ``t_ns`` arrival time, ns."""

    frame_type: FrameType
    raw: tuple[int, int, int, int]
    t_ns: int

    def encode(self) -> bytes:
        """The frame's 11 bytes on the wire."""
        return encode_frame(self.frame_type, self.raw)


@dataclass(frozen=True)
class ImuSample:
    """One complete BWT61CL sample in SI units.

    Attributes
    ----------
    t_ns : int
        Arrival time of the frame that completed the set (``time.monotonic_ns`` clock), ns.
    accel_m_s2 : ndarray, shape (3,), m/s^2
        Specific force in sensor axes.
    omega_rad_s : ndarray, shape (3,), rad/s
        Angular rate in sensor axes.
    euler_rad : ndarray, shape (3,), rad
        Roll, pitch, yaw (Z-Y-X convention) of the sensor.
    temperature_degC : float
        Chip temperature from the acceleration frame, degC.
    """

    t_ns: int
    accel_m_s2: np.ndarray
    omega_rad_s: np.ndarray
    euler_rad: np.ndarray
    temperature_degC: float


@dataclass
class ParserStats:
    """Counters of a :class:`Bwt61Parser` (all cumulative)."""

    bytes_in: int = 0
    frames: int = 0
    corrupt_frames: int = 0
    """Candidate frames (header, known type) with a bad checksum."""
    unknown_type: int = 0
    """Header bytes followed by a type other than 0x51..0x53."""
    skipped_bytes: int = 0
    """Bytes discarded while searching for a frame start."""
    dropped_frames: int = 0
    """Frames missing from the 0x51, 0x52, 0x53 sequence (lost or corrupt)."""
    samples: int = 0

    def copy(self) -> "ParserStats":
        """The counters as they are now (the parser goes on counting in ``self``)."""
        return replace(self)

    def since(self, earlier: "ParserStats") -> "ParserStats":
        """What was counted after ``earlier`` (a :meth:`copy` of these counters)."""
        return ParserStats(
            **{f.name: getattr(self, f.name) - getattr(earlier, f.name) for f in fields(self)}
        )

    def describe(self) -> str:
        """One line of what the parser saw: bytes, garbage skipped, frames, bad ones."""
        return (
            f"{self.bytes_in} bytes in, skipped {self.skipped_bytes} bytes, {self.frames} frames "
            f"({self.corrupt_frames} bad checksums, {self.unknown_type} unknown types, "
            f"{self.dropped_frames} dropped), {self.samples} samples"
        )


class Bwt61FrameParser:
    """Incremental frame parser: bytes in, checked frames out; never raises on stream content."""

    def __init__(self, stats: ParserStats | None = None) -> None:
        self.stats = stats if stats is not None else ParserStats()
        self._buf = bytearray()

    def feed(self, data: bytes, t_ns: int) -> list[ImuFrame]:
        """Add ``data`` (arrived at ``t_ns`` ns) and return the frames it completed."""
        self.stats.bytes_in += len(data)
        buf = self._buf
        buf += data
        frames = []
        start = 0
        while True:
            pos = buf.find(HEADER, start)
            if pos < 0:
                self.stats.skipped_bytes += len(buf) - start
                start = len(buf)
                break
            self.stats.skipped_bytes += pos - start
            start = pos
            if len(buf) - pos < 2:
                break
            if buf[pos + 1] not in _TYPES:
                self.stats.unknown_type += 1
                self.stats.skipped_bytes += 1
                start = pos + 1
                continue
            if len(buf) - pos < FRAME_LEN:
                break
            if buf[pos + 10] != sum(buf[pos : pos + 10]) & 0xFF:
                # Not a frame after all: resume the search inside it, where a real one may start.
                self.stats.corrupt_frames += 1
                self.stats.skipped_bytes += 1
                start = pos + 1
                continue
            raw = _INT16X4.unpack_from(buf, pos + 2)
            frames.append(ImuFrame(FrameType(buf[pos + 1]), raw, t_ns))
            start = pos + FRAME_LEN
        del buf[:start]
        self.stats.frames += len(frames)
        return frames


_TYPES = frozenset(int(t) for t in FrameType)
_ORDER = (FrameType.ACCEL, FrameType.RATE, FrameType.ANGLE)


class Bwt61SampleAssembler:
    """Combine 0x51, 0x52, 0x53 frames (in that order) into samples; count missing frames.

    A frame out of sequence means frames were lost: the partial set is discarded and the missing
    frames are counted as dropped. The first frame seen only synchronises the count.
    """

    def __init__(self, stats: ParserStats | None = None) -> None:
        self.stats = stats if stats is not None else ParserStats()
        self._pending: list[ImuFrame] = []
        self._next: int | None = None  # type that should follow the last frame seen

    def add(self, frame: ImuFrame) -> ImuSample | None:
        """Add one frame; return a sample when it completes a set, else ``None``."""
        kind = frame.frame_type
        if self._next is not None:
            self.stats.dropped_frames += (kind - self._next) % 3
        self._next = _ORDER[(_ORDER.index(kind) + 1) % 3]
        if kind == FrameType.ACCEL:
            self._pending = [frame]
        elif self._pending and kind == self._pending[-1].frame_type + 1:
            self._pending.append(frame)
        else:
            self._pending = []
        if len(self._pending) < 3:
            return None
        accel, rate, angle = self._pending
        self._pending = []
        self.stats.samples += 1
        return ImuSample(
            t_ns=angle.t_ns,
            accel_m_s2=np.array(accel.raw[:3], dtype=float) * ACCEL_SCALE_M_S2,
            omega_rad_s=np.array(rate.raw[:3], dtype=float) * RATE_SCALE_RAD_S,
            euler_rad=np.array(angle.raw[:3], dtype=float) * ANGLE_SCALE_RAD,
            temperature_degC=accel.raw[3] * TEMP_SCALE_DEGC + TEMP_OFFSET_DEGC,
        )


class Bwt61Parser:
    """Bytes in, samples out: :class:`Bwt61FrameParser` followed by the assembler.

    Examples
    --------
    >>> p = Bwt61Parser()
    >>> stream = b"".join(encode_frame(t, (0, 0, 2048, 0)) for t in (0x51, 0x52, 0x53))
    >>> [round(float(s.accel_m_s2[2]), 3) for s in p.feed(b"junk" + stream, t_ns=0)]
    [9.807]
    """

    def __init__(self) -> None:
        self.stats = ParserStats()
        self.frames = Bwt61FrameParser(self.stats)
        self.assembler = Bwt61SampleAssembler(self.stats)

    def feed(self, data: bytes, t_ns: int) -> list[ImuSample]:
        """Add ``data`` that arrived at ``t_ns`` ns; return the samples completed by it."""
        samples = []
        for frame in self.frames.feed(data, t_ns):
            sample = self.assembler.add(frame)
            if sample is not None:
                samples.append(sample)
        return samples


@dataclass
class Bwt61Driver:
    """BWT61CL on a serial port (USB-serial, ``/dev/rfcomm*`` or a pty).

    Parameters
    ----------
    port : str
        Serial device path.
    baud : int
        Baud rate, 115200 (100 Hz output) or 9600 (20 Hz).
    timeout_s : float
        Default wait of :meth:`read_sample`, s.
    """

    port: str
    baud: int = 115200
    timeout_s: float = 0.1
    parser: Bwt61Parser = field(default_factory=Bwt61Parser)
    _serial: serial.Serial | None = field(default=None, init=False, repr=False)
    _queue: list[ImuSample] = field(default_factory=list, init=False, repr=False)

    def open(self) -> "Bwt61Driver":
        """Open the port (idempotent); returns ``self``."""
        if self._serial is None:
            try:
                self._serial = LockedSerial(self.port, self.baud, timeout=0)
            except (serial.SerialException, OSError) as exc:
                raise ImuError(f"IMU: cannot open {self.port}: {exc}") from exc
        return self

    def close(self) -> None:
        """Close the port (idempotent)."""
        if self._serial is not None:
            self._serial.close()
            self._serial = None

    def __enter__(self) -> "Bwt61Driver":
        return self.open()

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @property
    def stats(self) -> ParserStats:
        """Parser counters: frames, corrupt, dropped, skipped bytes, samples."""
        return self.parser.stats

    def poll(self) -> list[ImuSample]:
        """Read whatever has arrived (no waiting) and return the completed samples."""
        ser = self._port()
        try:
            data = ser.read(max(ser.in_waiting, 1))
        except (serial.SerialException, OSError) as exc:
            raise ImuError(f"IMU: read from {self.port} failed: {exc}") from exc
        t_ns = time.monotonic_ns()
        out = self._queue + (self.parser.feed(data, t_ns) if data else [])
        self._queue = []
        return out

    def read_sample(self, timeout_s: float | None = None) -> ImuSample:
        """Return the next sample, waiting at most ``timeout_s`` s (default ``self.timeout_s``).

        Raises
        ------
        ImuTimeoutError
            No complete sample arrived in time (silent, stalled or corrupted link).
        """
        wait_s = self.timeout_s if timeout_s is None else timeout_s
        before = self.stats.copy()
        deadline = time.monotonic() + wait_s
        while True:
            samples = self.poll()
            if samples:
                self._queue = samples[1:]
                return samples[0]
            if time.monotonic() >= deadline:
                raise ImuTimeoutError(
                    f"IMU: no complete sample on {self.port} within {wait_s:.3f} s "
                    f"({self.stats.since(before).describe()})"
                )
            time.sleep(0.0005)

    def send_command(self, command: Command) -> None:
        """Write one ``FF AA xx`` configuration command."""
        try:
            self._port().write(command)
            self._port().flush()
        except (serial.SerialException, OSError) as exc:
            raise ImuError(f"IMU: write to {self.port} failed: {exc}") from exc

    def zero_yaw(self) -> None:
        """Make the present heading the zero of yaw."""
        self.send_command(ZERO_YAW)

    def calibrate_accelerometer(self) -> None:
        """Start the accelerometer calibration (device level and still)."""
        self.send_command(CALIBRATE_ACCEL)

    def set_mounting(self, mounting: str) -> None:
        """Select ``"horizontal"`` or ``"vertical"`` mounting."""
        commands = {"horizontal": MOUNT_HORIZONTAL, "vertical": MOUNT_VERTICAL}
        if mounting not in commands:
            raise ImuConfigError(f"IMU: mounting {mounting!r} is not one of {list(commands)}")
        self.send_command(commands[mounting])

    def set_rate(self, rate_hz: int) -> None:
        """Select 100 Hz (115200 baud) or 20 Hz (9600 baud); the port follows the new baud."""
        if rate_hz not in RATE_COMMANDS:
            raise ImuConfigError(f"IMU: rate {rate_hz} Hz is not one of {list(RATE_COMMANDS)} Hz")
        command, baud = RATE_COMMANDS[rate_hz]
        self.send_command(command)
        self._port().flush()
        self.baud = baud
        self._port().baudrate = baud

    def _port(self) -> serial.Serial:
        if self._serial is None:
            raise ImuError(f"IMU: port {self.port} is not open (call open())")
        return self._serial
