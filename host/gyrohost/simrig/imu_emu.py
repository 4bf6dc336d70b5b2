"""Emulated WitMotion BWT61CL on a pseudo-terminal.

The truth arrives through :class:`ImuTruth` (body angular rate, specific force, attitude), either
pushed with :meth:`Bwt61Emulator.set_truth` or pulled from ``truth_source(t_s)`` at every output
sample. The emulator rotates it into the sensor axes (mounting rotation ``mounting_rpy_rad``, turned
further by ``rotation_deg`` when the true mounting differs, then the device's horizontal/vertical
mode), adds MPU6050-like white noise (noise density times the
square root of half the output rate) and a constant bias drawn once, quantises to the int16 scales
of the wire format and sends 0x51, 0x52, 0x53 frames at 100 Hz or 20 Hz.

It answers the configuration commands: ``FF AA 52`` (present yaw becomes zero), ``67`` (the
accelerometer bias is removed, as a level calibration would), ``63``/``64`` (100 Hz/20 Hz; the pty
ignores baud), ``65``/``66`` (horizontal/vertical mode). Modelling choice, not from the datasheet:
vertical mode turns the output axes by -90 deg about the sensor x axis.
"""

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from gyrohost.config import ImuConfig
from gyrohost.drivers.imu import (
    ACCEL_SCALE_M_S2,
    ANGLE_SCALE_RAD,
    RATE_SCALE_RAD_S,
    STANDARD_GRAVITY_M_S2,
    TEMP_OFFSET_DEGC,
    TEMP_SCALE_DEGC,
    FrameType,
    encode_frame,
)
from gyrohost.geometry import euler_zyx, rotation_zyx, wrap_angle
from gyrohost.simrig.config import ImuEmuConfig
from gyrohost.simrig.faults import FaultFilter
from gyrohost.simrig.pty_link import PtyDevice


@dataclass(frozen=True)
class ImuTruth:
    """The true motion of the body the IMU is fixed to.

    Attributes
    ----------
    omega_rad_s : ndarray, shape (3,), rad/s
        Body angular rate in body axes.
    specific_force_m_s2 : ndarray, shape (3,), m/s^2
        Specific force (acceleration minus gravity) in body axes; at rest, level: (0, 0, g).
    R_wb : ndarray, shape (3, 3)
        Attitude: body axes expressed in the world frame (z up).
    """

    omega_rad_s: np.ndarray = field(default_factory=lambda: np.zeros(3))
    specific_force_m_s2: np.ndarray = field(
        default_factory=lambda: np.array([0.0, 0.0, STANDARD_GRAVITY_M_S2])
    )
    R_wb: np.ndarray = field(default_factory=lambda: np.eye(3))


def quantise(values: np.ndarray, scale: float) -> list[int]:
    """Raw int16 counts of ``values`` at ``scale`` units per count (rounded, saturated)."""
    counts = np.clip(np.rint(np.asarray(values) / scale), -32768, 32767)
    return [int(c) for c in counts]


TRUTH_WAIT_S = 0.02
"""Longest a sample waits for the truth to reach its time before it goes with an older state:
late but right is what a real sensor's link does to a sample; a state 5-15 ms old while the
D-bar turns at 2 rad/s is a sampling-time error no real sensor has. Two periods: with the
wire's 2.86 ms (100 Hz) inside the host's ``imu_max_delay_s`` (0.03 s)."""
MAX_BACKLOG_S = 0.1
"""Longest stall of the rig loop whose samples the emulator still sends, late (the truth keeps
this much history for them); a longer one loses the samples beyond, as a full UART buffer."""
_VERTICAL = rotation_zyx(-np.pi / 2, 0.0, 0.0)
_RATES = {0x63: 100, 0x64: 20}
_BAUDS = {100: 115200, 20: 9600}
SAMPLE_BITS = 3 * 11 * 10
"""Bits of one sample on the wire: three 11-byte frames, each byte a start bit, eight data bits
and a stop bit (8N1)."""


def wire_time_s(rate_hz: int) -> float:
    """How long one sample's bytes take on the wire at the baud rate of output rate ``rate_hz``
    (115200 baud at 100 Hz: 2.86 ms), s: its last byte, which completes it for the host, is
    that long after the first, sent when the sample was taken."""
    return SAMPLE_BITS / _BAUDS[rate_hz]


def sensor_in_body(mounting_rpy_rad, rotation_deg=(0.0, 0.0, 0.0)) -> np.ndarray:
    """The IMU's sensor axes in body axes (3, 3): the mounting ``mounting_rpy_rad`` (Z-Y-X, rad)
    turned further about the body axes by ``rotation_deg`` (Z-Y-X, deg)."""
    return rotation_zyx(*np.radians(rotation_deg)) @ rotation_zyx(*mounting_rpy_rad)


class Bwt61Emulator(PtyDevice):
    """BWT61CL emulator; see the module docstring.

    Parameters
    ----------
    emu : ImuEmuConfig, optional
        Noise, bias, temperature, seed and stream faults.
    imu : ImuConfig, optional
        Output rate and mounting (rotation and mode).
    truth_source : callable, optional
        ``truth_source(t_s) -> ImuTruth`` called at each output sample with its time on the
        output grid; when absent the last :meth:`set_truth` value (level and still at first)
        is used.
    truth_ready : callable, optional
        ``truth_ready(t_s) -> bool``: ``truth_source`` knows time ``t_s``; a sample waits for
        it up to :data:`TRUTH_WAIT_S` past its send time, then goes with what the source has.
    rotation_deg : sequence of 3 float, deg
        The sensor turned further by this roll, pitch, yaw (Z-Y-X, about the body axes) from
        where ``imu.mounting_rpy_rad`` puts it: a mounting the host's calibration does not know.
    """

    def __init__(
        self,
        emu: ImuEmuConfig | None = None,
        imu: ImuConfig | None = None,
        truth_source: Callable[[float], ImuTruth] | None = None,
        rotation_deg: Sequence[float] = (0.0, 0.0, 0.0),
        truth_ready: Callable[[float], bool] | None = None,
    ) -> None:
        emu = emu if emu is not None else ImuEmuConfig()
        imu = imu if imu is not None else ImuConfig()
        super().__init__(FaultFilter(emu.faults))
        self.emu = emu
        self.truth_source = truth_source
        self.truth_ready = truth_ready
        self.rate_hz = imu.rate_hz
        self.baud = _BAUDS[imu.rate_hz]
        self.vertical = imu.mounting == "vertical"
        # Sensor axes in body axes: the calibrated mounting, then turned about the body axes.
        self.R_bs = sensor_in_body(imu.mounting_rpy_rad, rotation_deg)
        self.yaw_offset_rad = 0.0
        self.samples_sent = 0
        self.commands_seen: list[int] = []
        self._rng = np.random.default_rng(emu.seed)
        self.gyro_bias_rad_s = self._rng.normal(0.0, emu.gyro_bias_std_rad_s, 3)
        self.accel_bias_m_s2 = self._rng.normal(0.0, emu.accel_bias_std_m_s2, 3)
        self._truth = ImuTruth()
        self._rx = bytearray()
        self._next_emit_s: float | None = None
        self._pending: bytes | None = None  # the next sample's bytes, before their send time

    # --- truth and configuration --------------------------------------------------------------
    def set_truth(
        self, omega_rad_s: np.ndarray, specific_force_m_s2: np.ndarray, R_wb: np.ndarray
    ) -> None:
        """Set the truth used from the next sample on (shapes (3,), (3,), (3, 3); SI units)."""
        truth = ImuTruth(
            np.array(omega_rad_s, dtype=float),
            np.array(specific_force_m_s2, dtype=float),
            np.array(R_wb, dtype=float),
        )
        with self.lock:
            self._truth = truth

    @property
    def period_s(self) -> float:
        """Output period, s."""
        return 1.0 / self.rate_hz

    def _R_bo(self) -> np.ndarray:
        """Output axes in body axes: mounting rotation, then the device's mode."""
        return self.R_bs @ _VERTICAL if self.vertical else self.R_bs

    # --- encoding -----------------------------------------------------------------------------
    def encode_sample(self, truth: ImuTruth) -> bytes:
        """The 33 bytes (0x51, 0x52, 0x53 frames) of one sample of ``truth``, noise included."""
        R_bo = self._R_bo()
        emu = self.emu
        rng = self._rng
        bandwidth_rthz = np.sqrt(self.rate_hz / 2.0)
        omega = R_bo.T @ truth.omega_rad_s + self.gyro_bias_rad_s
        omega += rng.normal(0.0, emu.gyro_noise_density_rad_s_rthz * bandwidth_rthz, 3)
        accel = R_bo.T @ truth.specific_force_m_s2 + self.accel_bias_m_s2
        accel += rng.normal(0.0, emu.accel_noise_density_m_s2_rthz * bandwidth_rthz, 3)
        euler = euler_zyx(truth.R_wb @ R_bo) + rng.normal(0.0, emu.angle_noise_std_rad, 3)
        euler[2] = float(wrap_angle(euler[2] - self.yaw_offset_rad))
        temp = int(round((emu.temperature_degC - TEMP_OFFSET_DEGC) / TEMP_SCALE_DEGC))
        return b"".join(
            (
                encode_frame(FrameType.ACCEL, (*quantise(accel, ACCEL_SCALE_M_S2), temp)),
                encode_frame(FrameType.RATE, (*quantise(omega, RATE_SCALE_RAD_S), temp)),
                encode_frame(FrameType.ANGLE, (*quantise(euler, ANGLE_SCALE_RAD), temp)),
            )
        )

    def _truth_known(self, t_s: float) -> bool:
        return self.truth_ready is None or self.truth_ready(t_s)

    def _current_truth(self, now_s: float) -> ImuTruth:
        return self.truth_source(now_s) if self.truth_source is not None else self._truth

    # --- PtyDevice hooks ----------------------------------------------------------------------
    @property
    def next_send_s(self) -> float | None:
        """When the next sample's last byte is due, s (None before the first tick): the rig's
        loop wakes then, so that the sample reaches the host as late as the wire makes it."""
        if self._next_emit_s is None:
            return None
        return self._next_emit_s + wire_time_s(self.rate_hz)

    def tick(self, now_s: float) -> None:
        if self._next_emit_s is None:  # the grid on the truth's steps (multiples of the
            # period from rig time zero): the truth of a sample is known by the time its
            # bytes have crossed the wire, not up to a step later, a delay no real sensor has
            self._next_emit_s = math.ceil(now_s / self.period_s - 1e-9) * self.period_s
        behind_s = now_s - self._next_emit_s - MAX_BACKLOG_S
        if behind_s > 0.0:  # a longer stall: its samples are lost, the grid's phase is kept
            self._next_emit_s += self.period_s * math.ceil(behind_s / self.period_s)
            self._pending = None
        # the device samples on its own grid whatever the rig loop does, as the real sensor's
        # clock does, and a sample is whole once its bytes have crossed the wire: samples the
        # loop was held up for go out late, together (the host puts them back on the grid);
        # each shows the truth at its grid time, once that is known (a truth lagging longer
        # than TRUTH_WAIT_S is sent as it stands)
        while now_s >= self._next_emit_s:
            if self._pending is None:  # encoded once the truth is known: the bytes then
                # wait for the wire only, not for the encoding's computation
                waited_s = now_s - self.next_send_s
                if waited_s < TRUTH_WAIT_S and not self._truth_known(self._next_emit_s):
                    return
                self._pending = self.encode_sample(self._current_truth(self._next_emit_s))
            if now_s < self.next_send_s:
                return
            self.send(self._pending, now_s)
            self._pending = None
            self.samples_sent += 1
            self._next_emit_s += self.period_s

    def handle_rx(self, data: bytes, now_s: float) -> None:
        self._rx += data
        while True:
            pos = self._rx.find(b"\xff\xaa")
            if pos < 0:
                del self._rx[:-1]  # a trailing 0xFF may start the next command
                return
            if len(self._rx) < pos + 3:
                del self._rx[:pos]
                return
            self._apply(self._rx[pos + 2], now_s)
            del self._rx[: pos + 3]

    def _apply(self, code: int, now_s: float) -> None:
        self.commands_seen.append(code)
        if code == 0x52:
            true_yaw = euler_zyx(self._current_truth(now_s).R_wb @ self._R_bo())[2]
            self.yaw_offset_rad = float(true_yaw)
        elif code == 0x67:
            self.accel_bias_m_s2 = np.zeros(3)
        elif code in _RATES:
            self.rate_hz = _RATES[code]
            self.baud = _BAUDS[self.rate_hz]
        elif code in (0x65, 0x66):
            self.vertical = code == 0x66
