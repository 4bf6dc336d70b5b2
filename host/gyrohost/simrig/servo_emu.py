"""Emulated Dynamixel MX-12W bus (Protocol 1.0) on a pseudo-terminal.

Each :class:`EmulatedMx12` keeps the MX-12W control table (addresses as in
``gyrohost.drivers.mx12.Addr``) and moves its position toward the goal at the moving speed (0 =
the no-load speed), quantised to 4096 steps per turn, in joint mode (clamped to CW..CCW limits),
multi-turn mode (CW = CCW = 4095, +-28672 steps) or wheel mode (CW = CCW = 0, speed only).

The bus answers PING, READ, WRITE, SYNC WRITE and BULK READ (replies in request order, stopping at
a servo that does not answer, as the real chain stalls), honours the status return level (0: ping
only, 1: reads, 2: all) and the return delay (2 us per unit). Unknown instructions get the
instruction error bit, a bad checksum the checksum error bit, writes to read-only addresses the
range bit and goals outside the angle limits the angle-limit bit.

Truth interface: :meth:`Mx12Bus.set_tension` gives the string tension, N, which sets the present
load (the servo's torque resisting the tension, ``-length_sign * T * r``, over the stall torque).
When that exceeds the torque limit the servo latches the overload bit and, as its shutdown byte
says by default, drops its torque; writing torque enable 1 clears the latch. The rig reads
:meth:`Mx12Bus.string_length_m` (the present rest length) to feed the model.

Motion: the position loop closes its error at the speed limit (the moving speed, or the no-load
speed) while the P gain's output asks for more, and as a first-order lag of the P gain's time
constant within (:func:`~gyrohost.drivers.mx12.position_lag_s`: 13.3 ms as shipped), so a goal
step every tick is followed smoothly. Near its goal the output no longer overcomes friction:
the servo stops there and holds until the goal changes; where, within ``hold_band_steps`` of
the goal, is drawn for each move (uniform, from ``seed`` and its ID). Its shaft, which the
truth reads, is continuous, its present position a count.

Modelling choices: with torque off the position stays (the MX gearbox is not back-driven here);
at power-up a servo sits anywhere within its hold band of its start (uniform, drawn from
``seed`` and its ID).
"""

import math
import random
import time
from collections import deque
from dataclasses import dataclass

import numpy as np

from gyrohost.config import MX_POSITION_LIMIT, ConfigError, ServoConfig
from gyrohost.drivers.mx12 import (
    LOAD_UNIT,
    MODEL_MX12W,
    MULTI_TURN_LIMIT,
    P_GAIN_FACTORY,
    SPEED_UNIT_RAD_S,
    STEPS_PER_TURN,
    Addr,
    int16_from_word,
    lag_error_after,
    position_lag_s,
    sign_magnitude_from_signed,
    signed_from_sign_magnitude,
    steps_to_length,
    word_from_int16,
)
from gyrohost.simrig.config import ServoEmuConfig
from gyrohost.simrig.faults import FaultFilter
from gyrohost.simrig.pty_link import PtyDevice

TABLE_SIZE = 74
BROADCAST_ID = 0xFE
INST_PING, INST_READ, INST_WRITE, INST_SYNC_WRITE, INST_BULK_READ = 0x01, 0x02, 0x03, 0x83, 0x92
ERR_ANGLE, ERR_RANGE, ERR_CHECKSUM, ERR_OVERLOAD, ERR_INSTRUCTION = 0x02, 0x08, 0x10, 0x20, 0x40

_DEFAULTS = {  # address: (value, size); MX-12W factory values (Protocol 1.0 manual)
    Addr.MODEL: (MODEL_MX12W, 2),
    2: (36, 1),  # firmware version
    Addr.ID: (1, 1),
    Addr.BAUD: (1, 1),  # 1 Mbps
    Addr.RETURN_DELAY: (250, 1),
    Addr.CW_LIMIT: (0, 2),
    Addr.CCW_LIMIT: (4095, 2),
    11: (80, 1),  # temperature limit, degC
    12: (60, 1),  # min voltage, 0.1 V
    13: (160, 1),  # max voltage, 0.1 V
    14: (1023, 2),  # max torque
    Addr.STATUS_RETURN: (2, 1),
    17: (36, 1),  # alarm LED
    Addr.SHUTDOWN: (36, 1),  # overheating | overload
    Addr.RESOLUTION_DIVIDER: (1, 1),
    26: (8, 1),  # D gain
    Addr.P_GAIN: (P_GAIN_FACTORY, 1),
    Addr.TORQUE_LIMIT: (1023, 2),
    42: (120, 1),  # present voltage, 0.1 V
    43: (30, 1),  # present temperature, degC
    48: (32, 2),  # punch
}
_READ_ONLY = set(range(0, 3)) | set(range(36, 47))


def status_packet(servo_id: int, error: int, params: bytes = b"") -> bytes:
    """A Protocol 1.0 status packet (same layout as an instruction, error in place of it)."""
    return Packet(servo_id, error, params, True).encode()


@dataclass(frozen=True)
class Packet:
    """One Protocol 1.0 packet as cut from a stream (``params`` without the checksum)."""

    servo_id: int
    instruction: int
    params: bytes
    checksum_ok: bool

    def encode(self) -> bytes:
        """The packet's bytes (with a correct checksum)."""
        body = bytes((self.servo_id, len(self.params) + 2, self.instruction)) + self.params
        return b"\xff\xff" + body + bytes(((~sum(body)) & 0xFF,))


class PacketCutter:
    """Incremental Protocol 1.0 packet cutter: bytes in, :class:`Packet` out; never raises.

    A packet with a bad checksum is reported (``checksum_ok`` False) and only its header is
    consumed, so a real packet hidden inside a bogus length is still found.
    """

    def __init__(self) -> None:
        self._rx = bytearray()

    def feed(self, data: bytes) -> list[Packet]:
        """Add ``data``; return the packets it completed."""
        self._rx += data
        packets = []
        while (packet := self._next()) is not None:
            packets.append(packet)
        return packets

    def _next(self) -> Packet | None:
        rx = self._rx
        while True:
            pos = rx.find(b"\xff\xff")
            if pos < 0:
                del rx[:-1]  # a trailing 0xFF may start the next header
                return None
            del rx[:pos]
            if len(rx) < 4:
                return None
            if rx[2] == 0xFF or rx[3] < 2:  # a third 0xFF or an impossible length: resync
                del rx[:1]
                continue
            total = rx[3] + 4
            if len(rx) < total:
                return None
            ok = rx[total - 1] == (~sum(rx[2 : total - 1])) & 0xFF
            packet = Packet(rx[2], rx[4], bytes(rx[5 : total - 1]), ok)
            del rx[: total if ok else 2]
            return packet


class EmulatedMx12:
    """One MX-12W: control table, motion and load.

    Parameters
    ----------
    servo_id : int
    emu : ServoEmuConfig
        Motor figures (no-load speed, stall torque) and the return delay.
    spec : ServoConfig, optional
        String calibration: sets the start position (the calibrated zero) and lets
        :meth:`string_length_m` and the load direction follow the real geometry.
    """

    def __init__(self, servo_id: int, emu: ServoEmuConfig, spec: ServoConfig | None = None):
        self.table = bytearray(TABLE_SIZE)
        for addr, (value, size) in _DEFAULTS.items():
            self.table[addr : addr + size] = value.to_bytes(size, "little")
        self.table[Addr.ID] = servo_id
        self.table[Addr.RETURN_DELAY] = min(emu.return_delay_us // 2, 254)
        self.emu = emu
        self.spec = spec
        self.tension_N = 0.0
        self.forced_overload = False
        self.no_reply = False
        self._rng = random.Random(emu.seed * 1000 + servo_id)
        self.reset()

    def reset(self) -> None:
        """Back to the start position (the calibrated zero, held within the band), at rest,
        that position the goal; an overload latched by tension is cleared (mode and torque
        stay)."""
        start = self.spec.zero_position if self.spec is not None else 0
        self.position_steps = self._settle(start)
        self._moving_to, self._stop_steps = None, 0.0
        self.velocity_steps_s = 0.0
        self.overload_latched = False
        self._store_goal(start)

    def _settle(self, goal: int) -> float:
        """Where the shaft sits at power-up at ``goal``, steps: anywhere within the hold band."""
        self._held_goal = goal
        band = self.emu.hold_band_steps
        return goal + self._rng.uniform(-band, band)

    # --- control table ------------------------------------------------------------------------
    def word(self, addr: int) -> int:
        return self.table[addr] | self.table[addr + 1] << 8

    def _store_goal(self, steps: int) -> None:
        self.table[Addr.GOAL_POSITION : Addr.GOAL_POSITION + 2] = word_from_int16(steps).to_bytes(
            2, "little"
        )

    @property
    def servo_id(self) -> int:
        return self.table[Addr.ID]

    @property
    def mode(self) -> str:
        cw, ccw = self.word(Addr.CW_LIMIT), self.word(Addr.CCW_LIMIT)
        if cw == ccw == MULTI_TURN_LIMIT:
            return "multi-turn"
        return "wheel" if cw == ccw == 0 else "joint"

    @property
    def torque_on(self) -> bool:
        return bool(self.table[Addr.TORQUE_ENABLE])

    def error_byte(self) -> int:
        """Error bits every status packet carries now."""
        return ERR_OVERLOAD if (self.overload_latched or self.forced_overload) else 0

    def read(self, addr: int, n: int) -> tuple[bytes, int]:
        """Read ``n`` bytes at ``addr``; returns (data, extra error bits)."""
        if addr + n > TABLE_SIZE or n == 0:
            return b"", ERR_RANGE
        self._refresh_present()
        return bytes(self.table[addr : addr + n]), 0

    def write(self, addr: int, data: bytes) -> int:
        """Write ``data`` at ``addr``; returns the extra error bits (range, angle limit)."""
        end = addr + len(data)
        if end > TABLE_SIZE or not data or _READ_ONLY & set(range(addr, end)):
            return ERR_RANGE
        goal_before = bytes(self.table[Addr.GOAL_POSITION : Addr.GOAL_POSITION + 2])
        self.table[addr:end] = data
        if addr <= Addr.TORQUE_ENABLE < end and self.table[Addr.TORQUE_ENABLE]:
            self.overload_latched = False
        if addr < Addr.GOAL_POSITION + 2 and end > Addr.GOAL_POSITION and not self._goal_ok():
            self.table[Addr.GOAL_POSITION : Addr.GOAL_POSITION + 2] = goal_before
            return ERR_ANGLE
        return 0

    def _goal(self) -> int:
        word = self.word(Addr.GOAL_POSITION)
        return int16_from_word(word) if self.mode == "multi-turn" else word

    def _goal_ok(self) -> bool:
        goal = self._goal()
        if self.mode == "multi-turn":
            return abs(goal) <= MX_POSITION_LIMIT
        if self.mode == "joint":
            return self.word(Addr.CW_LIMIT) <= goal <= self.word(Addr.CCW_LIMIT)
        return True

    # --- physics ------------------------------------------------------------------------------
    def torque_N_m(self) -> float:
        """Torque the servo must apply against the string tension, N m (positive = CCW)."""
        radius = self.spec.pulley_radius_m if self.spec is not None else 0.01
        sign = self.spec.length_sign if self.spec is not None else 1
        return -sign * self.tension_N * radius

    def advance(self, dt_s: float) -> float | None:
        """Move for ``dt_s`` s and update the overload state; returns how far into ``dt_s``
        (s) a move reached its goal, or None (still on its way, or not moving)."""
        torque_limit = self.word(Addr.TORQUE_LIMIT) / 1023.0 * self.emu.stall_torque_N_m
        if self.torque_on and abs(self.torque_N_m()) > torque_limit:
            self.overload_latched = True
            if self.table[Addr.SHUTDOWN] & ERR_OVERLOAD:
                self.table[Addr.TORQUE_ENABLE] = 0
        if not self.torque_on or self.error_byte():
            self.velocity_steps_s = 0.0
            return None
        speed_units = self.word(Addr.MOVING_SPEED)
        no_load = self.emu.no_load_speed_rpm / 0.916
        if self.mode == "wheel":
            units = signed_from_sign_magnitude(speed_units)
            self.velocity_steps_s = _units_to_steps_s(max(min(units, no_load), -no_load))
            self.position_steps += self.velocity_steps_s * dt_s
            self._held_goal = None
            return None
        goal = self._goal()
        if goal == self._held_goal and abs(goal - self.position_steps) <= self.emu.hold_band_steps:
            self.velocity_steps_s = 0.0
            return None
        if goal != self._moving_to:  # a new move: where friction will stop this one
            self._moving_to = goal
            self._stop_steps = self._rng.uniform(0.0, self.emu.hold_band_steps)
        max_steps_s = _units_to_steps_s(min(speed_units or no_load, no_load))
        lag_s = position_lag_s(self.table[Addr.P_GAIN], self.emu.no_load_speed_rpm)
        error, arrived = _approach(
            goal - self.position_steps, dt_s, lag_s, max_steps_s, self._stop_steps
        )
        step = goal - error - self.position_steps
        self.position_steps = goal - error
        self._held_goal = goal if arrived is not None else None
        self.velocity_steps_s = step / dt_s if dt_s > 0 else 0.0
        return arrived

    def _refresh_present(self) -> None:
        position = int(round(self.position_steps))
        if self.mode == "multi-turn":
            position = max(min(position, MX_POSITION_LIMIT), -MX_POSITION_LIMIT)
            word = word_from_int16(position)
        else:
            word = position % STEPS_PER_TURN
        speed = round(self.velocity_steps_s * 2 * math.pi / STEPS_PER_TURN / SPEED_UNIT_RAD_S)
        load = 0.0
        if self.torque_on:
            load = self.torque_N_m() / self.emu.stall_torque_N_m / LOAD_UNIT
        load_units = max(min(round(load), 1023), -1023)
        self.table[36:38] = word.to_bytes(2, "little")
        self.table[38:40] = sign_magnitude_from_signed(max(min(speed, 1023), -1023)).to_bytes(
            2, "little"
        )
        self.table[40:42] = sign_magnitude_from_signed(load_units).to_bytes(2, "little")
        band = max(self.emu.hold_band_steps, 0.5)
        self.table[Addr.MOVING] = int(abs(self._goal() - self.position_steps) > band)

    def string_length_m(self) -> float:
        """Present string length from the calibration, m (needs ``spec``)."""
        if self.spec is None:
            raise ValueError(f"emulated servo ID {self.servo_id} has no string calibration")
        return steps_to_length(self.spec, self.position_steps)


class ServoPath:
    """A servo's position over emulator time, as straight pieces through the positions of its
    ticks: a point that its piece's line passes within :data:`PATH_TOLERANCE_STEPS` of (with
    every point that piece already absorbed) moves the piece's end instead of adding one. A
    hold or a move at the speed limit is one piece; a lag's curve a piece every tick or few,
    bending where a move starts (a tick after a new goal) and where it stops (within a tick, at
    the time :meth:`EmulatedMx12.advance` gives). The truth steps its physics through these
    bends (:meth:`gyrohost.simrig.truth.Truth.step`), so a rest length moves when the servo
    does, not spread over the truth's step.

    Only the bends of the last :data:`PATH_KEPT_S` are kept."""

    def __init__(self):
        self.t_s: deque = deque()
        self.steps: deque = deque()
        self._slopes = (-math.inf, math.inf)  # the last piece's slopes its points allow

    def add(self, t_s: float, position_steps: float) -> None:
        """The position at ``t_s`` (after every point added so far)."""
        t, p = self.t_s, self.steps
        if t and t_s <= t[-1]:
            return
        if len(t) >= 2:
            lo, hi = self._slopes_through(t[-2], p[-2], t[-1], p[-1])
            if lo <= (position_steps - p[-2]) / (t_s - t[-2]) <= hi:
                self._slopes = (lo, hi)
                t[-1], p[-1] = t_s, position_steps
                return
        self._slopes = (-math.inf, math.inf)
        t.append(t_s)
        p.append(position_steps)
        while len(t) > 2 and t[1] < t_s - PATH_KEPT_S:
            t.popleft()
            p.popleft()

    def _slopes_through(self, t0, p0, t1, p1) -> tuple[float, float]:
        """The slopes of the lines from (t0, p0) that pass within the tolerance of (t1, p1)
        and of every point the piece absorbed before (kept as their intersection: each point
        is checked once)."""
        lo, hi = self._slopes
        dt, tol = t1 - t0, PATH_TOLERANCE_STEPS
        return max(lo, (p1 - tol - p0) / dt), min(hi, (p1 + tol - p0) / dt)

    def steps_at(self, t_s: float) -> float:
        """The position at ``t_s``, steps (the nearest end outside the path)."""
        return float(np.interp(t_s, self.t_s, self.steps))

    def turns(self, t0_s: float, t1_s: float) -> list[float]:
        """The bends strictly between ``t0_s`` and ``t1_s``."""
        return [t for t in list(self.t_s)[:-1] if t0_s < t < t1_s]


PATH_KEPT_S = 1.0
"""Emulator time a servo's path is kept for, s: far more than the truth lags its devices."""
PATH_TOLERANCE_STEPS = 0.02
"""How far the path's straight pieces may pass from the positions they stand for, steps: a
fiftieth of the count the servo reads (0.3 um of string on a 1 cm pulley)."""


def _approach(error, dt_s, lag_s, max_steps_s, band_steps):
    """The position loop's error after ``dt_s`` s from ``error`` (steps), and how far into
    ``dt_s`` (s) it fell to ``band_steps`` (where the output no longer overcomes friction and
    the servo stops), or None: :func:`~gyrohost.drivers.mx12.lag_error_after`, exact, so the
    path does not depend on the ticks."""
    size = abs(error)
    if size <= band_steps:
        return error, 0.0
    knee = max_steps_s * lag_s
    to_knee = (size - knee) / max_steps_s if size > knee else 0.0
    to_band = math.inf
    if band_steps > 0:
        to_band = to_knee + lag_s * math.log(min(size, knee) / band_steps)
    if dt_s >= to_band:
        return math.copysign(band_steps, error), to_band
    return float(lag_error_after(error, dt_s, lag_s, max_steps_s)), None


def _units_to_steps_s(units: float) -> float:
    return units * SPEED_UNIT_RAD_S * STEPS_PER_TURN / (2 * math.pi)


class Mx12Bus(PtyDevice):
    """A Dynamixel bus of emulated MX-12W servos behind one pty (the U2D2's place).

    Parameters
    ----------
    servos : sequence of ServoConfig
        The servos on the bus (IDs and string calibrations).
    emu : ServoEmuConfig, optional
        Motor figures, return delay, servo faults and stream faults.
    """

    def __init__(self, servos, emu: ServoEmuConfig | None = None) -> None:
        emu = emu if emu is not None else ServoEmuConfig()
        super().__init__(FaultFilter(emu.faults))
        self.servos = {s.id: EmulatedMx12(s.id, emu, s) for s in servos}
        for key, ids in (("overload_ids", emu.overload_ids), ("no_reply_ids", emu.no_reply_ids)):
            unknown = sorted(set(ids) - set(self.servos))
            if unknown:
                self.close()
                have = sorted(self.servos)
                raise ConfigError(
                    f"sim.servos.{key}: IDs {unknown} are not on the bus (have {have})"
                )
        for servo_id in emu.overload_ids:
            self.servos[servo_id].forced_overload = True
        for servo_id in emu.no_reply_ids:
            self.servos[servo_id].no_reply = True
        self.packets_seen = 0
        self.bad_checksums = 0
        self.cutter = PacketCutter()
        self._last_s: float | None = None
        self.paths = {sid: ServoPath() for sid in self.servos}

    # --- truth and fault hooks ----------------------------------------------------------------
    def _servo(self, servo_id: int) -> EmulatedMx12:
        if servo_id not in self.servos:
            raise KeyError(f"no emulated servo with ID {servo_id} (have {sorted(self.servos)})")
        return self.servos[servo_id]

    def set_tension(self, servo_id: int, tension_N: float) -> None:
        """String tension pulling on servo ``servo_id``, N."""
        with self.lock:
            self._servo(servo_id).tension_N = float(tension_N)

    def set_overload(self, servo_id: int, on: bool) -> None:
        """Force the overload fault on or off (independent of the tension)."""
        with self.lock:
            self._servo(servo_id).forced_overload = on

    def set_no_reply(self, servo_id: int, on: bool) -> None:
        """Make servo ``servo_id`` ignore every packet (the driver sees a timeout)."""
        with self.lock:
            self._servo(servo_id).no_reply = on

    def reset(self) -> None:
        """Every servo back to its start position (:meth:`EmulatedMx12.reset`)."""
        with self.lock:
            for servo in self.servos.values():
                servo.reset()
            self.paths = {sid: ServoPath() for sid in self.servos}

    def string_length_m(self, servo_id: int) -> float:
        """Present string length of servo ``servo_id``, m: the rest length for the model."""
        with self.lock:
            return self._servo(servo_id).string_length_m()

    def position_steps(self, servo_id: int) -> float:
        """Present position of servo ``servo_id``, steps (unquantised)."""
        with self.lock:
            return self._servo(servo_id).position_steps

    # --- PtyDevice hooks ----------------------------------------------------------------------
    def lengths_at(self, t_s: float) -> dict[int, float]:
        """Each servo's string length (ID -> m) at emulator time ``t_s`` on its path: the
        present one from the last tick on (or before any tick), the first kept before it."""
        with self.lock:
            out = {}
            for sid, servo in self.servos.items():
                path = self.paths.get(sid)
                steps = path.steps_at(t_s) if path and path.t_s else servo.position_steps
                out[sid] = self._length_of(sid, steps)
            return out

    def turns_between(self, t0_s: float, t1_s: float) -> list[float]:
        """The emulator times strictly between ``t0_s`` and ``t1_s`` at which a servo on the
        bus changed speed (its path is straight between them and the ticks), sorted."""
        with self.lock:
            paths = [self.paths[sid] for sid in self.servos if sid in self.paths]
            return sorted({t for p in paths for t in p.turns(t0_s, t1_s)})

    def _length_of(self, servo_id: int, position_steps: float) -> float:
        servo = self.servos[servo_id]
        return steps_to_length(servo.spec, position_steps) if servo.spec is not None else 0.0

    def tick(self, now_s: float) -> None:
        for sid, servo in self.servos.items():
            path = self.paths.setdefault(sid, ServoPath())  # a servo given a new ID: a new path
            if self._last_s is not None and now_s > self._last_s:
                arrived = servo.advance(now_s - self._last_s)
                if arrived is not None and 0.0 < arrived < now_s - self._last_s:
                    path.add(self._last_s + arrived, servo.position_steps)
            path.add(now_s, servo.position_steps)
        self._last_s = now_s

    def handle_rx(self, data: bytes, now_s: float) -> None:
        for packet in self.cutter.feed(data):
            self._dispatch(packet, now_s)

    def _dispatch(self, packet: Packet, now_s: float) -> None:
        servo_id, inst, params = packet.servo_id, packet.instruction, packet.params
        self.packets_seen += 1
        if not packet.checksum_ok:
            self.bad_checksums += 1
            if servo_id in self.servos:
                self._reply(self.servos[servo_id], ERR_CHECKSUM, b"", now_s)
            return
        if servo_id == BROADCAST_ID:
            self._broadcast(inst, params, now_s)
        elif servo_id in self.servos:
            self._unicast(self.servos[servo_id], inst, params, now_s)
        if inst == INST_WRITE:  # an ID written: the servo answers to the new one from now on
            self.servos = {servo.servo_id: servo for servo in self.servos.values()}

    def _unicast(self, servo: EmulatedMx12, inst: int, params: bytes, now_s: float) -> None:
        if servo.no_reply:
            return
        level = servo.table[Addr.STATUS_RETURN]
        if inst == INST_PING:
            self._reply(servo, 0, b"", now_s)
        elif inst == INST_READ and len(params) == 2:
            data, err = servo.read(params[0], params[1])
            if level >= 1:
                self._reply(servo, err, data, now_s)
        elif inst == INST_WRITE and len(params) >= 2:
            err = servo.write(params[0], params[1:])
            if level >= 2:
                self._reply(servo, err, b"", now_s)
        elif level >= 2:
            self._reply(servo, ERR_INSTRUCTION, b"", now_s)

    def _broadcast(self, inst: int, params: bytes, now_s: float) -> None:
        if inst == INST_WRITE and len(params) >= 2:
            for servo in self.servos.values():
                if not servo.no_reply:
                    servo.write(params[0], params[1:])
        elif inst == INST_SYNC_WRITE and len(params) >= 2:
            addr, n = params[0], params[1]
            for i in range(2, len(params) - n, n + 1):
                servo = self.servos.get(params[i])
                if servo is not None and not servo.no_reply:
                    servo.write(addr, params[i + 1 : i + 1 + n])
        elif inst == INST_BULK_READ and len(params) >= 1:
            for i in range(1, len(params) - 2, 3):
                n, servo_id, addr = params[i], params[i + 1], params[i + 2]
                servo = self.servos.get(servo_id)
                if servo is None or servo.no_reply:
                    return  # the next servo in the chain waits for this reply forever
                data, err = servo.read(addr, n)
                self._reply(servo, err, data, now_s)

    def _reply(self, servo: EmulatedMx12, error: int, params: bytes, now_s: float) -> None:
        if servo.no_reply:
            return
        delay_s = servo.table[Addr.RETURN_DELAY] * 2e-6
        if delay_s > 0:
            time.sleep(delay_s)
        self.send(status_packet(servo.servo_id, error | servo.error_byte(), params), now_s)
