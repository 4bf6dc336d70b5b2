"""Two (or more) Dynamixel MX-12W string servos through dynamixel-sdk, Protocol 1.0.

Each servo winds one string on a pulley of radius ``r`` in multi-turn mode (CW = CCW = 4095,
positions -28672..28672 steps, 4096 steps per turn). The string length is
``L = length_at_zero_m + length_sign * (p - zero_position) * 2 pi r / 4096`` (see
:func:`gyrohost.drivers.mx12.steps_to_length`; the control table and unit conversions live in
:mod:`gyrohost.drivers.mx12`). Limits on length and speed are checked before anything is sent:
a command outside them is refused with :class:`ServoLimitError` naming the servo, value and limit
(rounding, within ``LENGTH_ROUNDING_M`` of a limit, is commanded at the limit; the goal position
never maps to a length beyond it).

SDK facts this module relies on (field notes section 5, dynamixel-sdk 4.1.0):

- ``GroupBulkRead.txRxPacket`` raises ``TypeError`` for Protocol 1.0; the bulk read here calls
  ``makeParam``, ``bulkReadTx`` and one ``readRx`` per servo itself (which also keeps each
  servo's error byte, which the group discards). ``read_mode = "per_servo"`` uses ``readTxRx``.
- The SDK returns raw unsigned words: positions are 16-bit two's complement, present speed and
  load are sign-magnitude (bit 10 = clockwise = negative here); converted by ``mx12``.
- ``GroupSyncWrite`` is a broadcast without a status reply: goals are confirmed by reading back.
- pyserial's low-latency ioctl fails on a pty; it is attempted and the failure tolerated.
- The SDK's fixed 34 ms reply timeout and busy-wait are replaced (``PortHandler``) by
  ``reply_timeout_s`` from the configuration and reads that sleep in ``select``.
"""

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import dynamixel_sdk as sdk
import serial

from gyrohost.config import MX_POSITION_LIMIT, ServoBusConfig, ServoConfig
from gyrohost.drivers import mx12

from .errors import (
    ServoCommError,
    ServoError,
    ServoFaultError,
    ServoLimitError,
    ServoTimeoutError,
)
from .portlock import PortClaim, exclusive_serial


@dataclass(frozen=True)
class ServoState:
    """One servo read back.

    Attributes
    ----------
    name : str
    servo_id : int
    position_steps : int
        Present position, steps (multi-turn, signed).
    length_m : float
        String length at that position, m.
    speed_m_s : float
        Rate of change of the string length, m/s.
    load_fraction : float
        Present load, fraction of the maximum torque; positive = counter-clockwise torque.
    faults : tuple of str
        Fault names from the status error byte (empty when healthy).
    t_ns : int
        ``time.monotonic_ns`` when the servo sampled it (the midpoint of request and reply; a
        bulk read's request), ns.
    """

    name: str
    servo_id: int
    position_steps: int
    length_m: float
    speed_m_s: float
    load_fraction: float
    faults: tuple[str, ...]
    t_ns: int


STATE_BYTES = mx12.Addr.PRESENT_LOAD + 2 - mx12.Addr.PRESENT_POSITION
"""Bytes of a servo's state read: present position, speed and load."""
LENGTH_ROUNDING_M = 1e-9
"""A length commanded this close outside a servo's length limit is rounding (a schedule sampled
or planned on the limit): it is commanded at the limit. Farther out it is refused."""


class PortHandler(sdk.PortHandler):
    """dynamixel-sdk port with a configurable reply timeout and reads that wait a little.

    The SDK times a reply out after the transfer time plus ``2 * LATENCY_TIMER + 2`` = 34 ms, and
    polls the port with a zero read timeout (a busy-wait that holds the GIL). Here the margin is
    ``reply_timeout_s`` and each poll may wait up to ``READ_SLICE_S`` for bytes, sleeping in
    ``select`` instead of spinning.
    """

    READ_SLICE_S = 0.0005
    QUIET_S = 0.002
    """No byte for this long after a request or a byte: no status packet is under way (a servo
    answers within its return delay, 0.5 ms at the factory setting, and sends its packet back to
    back), so :attr:`while_waiting` may write without cutting into one."""

    def __init__(self, port_name: str, reply_timeout_s: float) -> None:
        super().__init__(port_name)
        self.reply_timeout_ms = reply_timeout_s * 1000.0
        self._claim: PortClaim | None = None
        self.while_waiting = None
        """Callable run while a reply is awaited and the line is quiet (goals that must not
        wait for a silent servo's time-out); it may write whole packets, never read."""
        self._last_rx_s = 0.0
        self.written_ns = 0
        """``time.monotonic_ns()`` just before the newest packet went to the OS: a stamp taken
        before the SDK's own work around the write was late by up to milliseconds where the
        thread waited for the GIL in between (0.5-1.4 ms at the 99th percentile of goals)."""
        self.in_reply_wait = False
        """True while :attr:`while_waiting` runs: a packet must then go out without the SDK's
        ``txPacket``, which flushes the input (the reply awaited, or the next one of a bulk
        read, may be in it already)."""

    def setupPort(self, cflag_baud: int) -> bool:
        """(Re)open the port at ``self.baudrate``, exclusively (:mod:`gyrohost.drivers.
        portlock`); the new claim is taken before a reopen drops the old one, so no other
        process slips in at a baud change.

        Raises
        ------
        PortBusyError
            Another process holds the port.
        """
        claim = PortClaim(self.port_name)
        try:
            if self.is_open:
                self.closePort()
            self.ser = exclusive_serial(
                self.port_name, self.baudrate, bytesize=serial.EIGHTBITS, timeout=self.READ_SLICE_S
            )
        except BaseException:
            claim.release()
            raise
        self._claim, self.is_open = claim, True
        self.ser.reset_input_buffer()
        self.tx_time_per_byte = (1000.0 / self.baudrate) * 10.0
        return True

    def closePort(self) -> None:
        try:
            super().closePort()
        finally:
            if self._claim is not None:
                self._claim.release()
                self._claim = None

    def setPacketTimeout(self, packet_length: int) -> None:
        self.packet_start_time = self.getCurrentTime()
        self.packet_timeout = self.tx_time_per_byte * packet_length + self.reply_timeout_ms
        self._last_rx_s = time.monotonic()

    def writePort(self, packet) -> int:
        self.written_ns = time.monotonic_ns()
        return super().writePort(packet)

    def readPort(self, length: int) -> bytes:
        data = super().readPort(length)
        if data:
            self._last_rx_s = time.monotonic()
        return data

    def isPacketTimeout(self) -> bool:
        """The SDK asks this between reads while it waits for a reply: the quiet line's
        moment for :attr:`while_waiting` (not re-entered from inside it).

        Bytes waiting in the port are never a time-out, however late it is: a thread held off
        the CPU past the time-out (a loaded host) would otherwise declare silent a servo whose
        reply sits unread.
        """
        hook = self.while_waiting
        if hook is not None and time.monotonic() - self._last_rx_s >= self.QUIET_S:
            self.while_waiting, self.in_reply_wait = None, True
            try:
                hook()
            finally:
                self.while_waiting, self.in_reply_wait = hook, False
        return super().isPacketTimeout() and not self.ser.in_waiting

    def write_packet(self, packet: bytes) -> None:
        """Write a whole packet now, inside a transaction the SDK holds (its ``txPacket`` would
        refuse it as busy and flush the reply under way)."""
        written = self.writePort(packet)
        if written != len(packet):
            raise ServoCommError(
                f"servo bus {self.port_name}: wrote {written} of {len(packet)} bytes",
                sdk.BROADCAST_ID,
                sdk.COMM_TX_FAIL,
            )


def _set_low_latency(port: sdk.PortHandler) -> bool:
    """Ask for the FTDI low-latency mode; a pty (or non-Linux) refuses, which is fine."""
    try:
        port.ser.set_low_latency_mode(True)
    except (ValueError, OSError, NotImplementedError, AttributeError):
        return False
    return True


class StringServoBus:
    """MX-12W string servos on one Dynamixel bus.

    Parameters
    ----------
    config : ServoBusConfig
        Port, baud, read mode and the servos (calibration and limits).
    """

    def __init__(self, config: ServoBusConfig) -> None:
        if not config.servo:
            raise ServoLimitError(f"servo bus on {config.port}: no servos configured")
        self.config = config
        self.servos = {s.name: s for s in config.servo}
        for servo in config.servo:
            _check_config_limits(servo)
        self.port = PortHandler(config.port, config.reply_timeout_s)
        self.packets = sdk.PacketHandler(1.0)
        self.low_latency = False
        self.goals_sent_ns = 0  # time.monotonic_ns() just before the newest goals went to the OS
        self._open = False

    # --- port ---------------------------------------------------------------------------------
    @property
    def reply_timeout_s(self) -> float:
        """Longest wait for a status packet beyond its transfer time, s."""
        return self.port.reply_timeout_ms / 1000.0

    @reply_timeout_s.setter
    def reply_timeout_s(self, value_s: float) -> None:
        if not (math.isfinite(value_s) and value_s > 0):
            raise ServoLimitError(f"servo bus: reply timeout {value_s} s must be positive")
        self.port.reply_timeout_ms = value_s * 1000.0

    def on_reply_wait(self, hook) -> None:
        """Run ``hook()`` (None: nothing) while a reply is awaited and the line is quiet; it may
        send goals (:meth:`command_lengths`), which then need not wait for a silent servo."""
        self.port.while_waiting = hook

    def open(self) -> "StringServoBus":
        """Open the port at the configured baud rate (idempotent); returns ``self``."""
        if self._open:
            return self
        try:
            opened = self.port.openPort() and self.port.setBaudRate(self.config.baud)
        except OSError as exc:  # pyserial's SerialException is an OSError
            raise ServoError(f"servo bus: cannot open {self.config.port}: {exc}") from exc
        if not opened:
            raise ServoError(f"servo bus: {self.config.port} refused baud {self.config.baud}")
        self.low_latency = _set_low_latency(self.port)
        self._open = True
        return self

    def close(self) -> None:
        """Close the port (idempotent)."""
        if self._open:
            self.port.closePort()
            self._open = False

    def __enter__(self) -> "StringServoBus":
        return self.open()

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # --- setup --------------------------------------------------------------------------------
    def ping_all(self) -> dict[str, int]:
        """Ping every servo; return name -> model number. Raises if one is not an MX-12W."""
        models = {}
        for servo in self.config.servo:
            model, result, error = self.packets.ping(self.port, servo.id)
            self._check(servo, result, error, "ping")
            if model != mx12.MODEL_MX12W:
                raise ServoError(
                    f"servo '{servo.name}' (ID {servo.id}): model {model}, expected MX-12W "
                    f"({mx12.MODEL_MX12W})"
                )
            models[servo.name] = model
        return models

    def configure(self) -> None:
        """Ping, select multi-turn mode (CW = CCW = 4095), enable torque and hold position."""
        self.ping_all()
        for servo in self.config.servo:
            for addr in (mx12.Addr.CW_LIMIT, mx12.Addr.CCW_LIMIT):
                result, error = self.packets.write2ByteTxRx(
                    self.port, servo.id, addr, mx12.MULTI_TURN_LIMIT
                )
                self._check(servo, result, error, f"write angle limit at {addr}")
        self.hold()

    def set_torque(self, enable: bool) -> None:
        """Enable or disable the torque of every servo."""
        for servo in self.config.servo:
            result, error = self.packets.write1ByteTxRx(
                self.port, servo.id, mx12.Addr.TORQUE_ENABLE, int(enable)
            )
            self._check(servo, result, error, "write torque enable")

    # --- commands -----------------------------------------------------------------------------
    def command_lengths(
        self,
        lengths_m: Mapping[str, float] | Sequence[float],
        speeds_m_s: Mapping[str, float] | Sequence[float] | None = None,
    ) -> dict[str, int]:
        """Send string length goals (and speed limits) to the servos in one sync write.

        Parameters
        ----------
        lengths_m : mapping name -> float, or sequence in configuration order, m
            Goal string lengths.
        speeds_m_s : same form, optional, m/s
            Speed limits (positive); each servo's ``max_speed_m_s`` when omitted.

        Returns
        -------
        dict
            Servo name -> goal position sent, steps.

        Raises
        ------
        ServoLimitError
            A length or speed is outside its limit; then nothing at all is sent.
        """
        lengths = self._by_name(lengths_m, "lengths_m")
        speeds = self._by_name(speeds_m_s, "speeds_m_s") if speeds_m_s is not None else {}
        goals = {}
        for name, length in lengths.items():
            servo = self.servos[name]
            speed = speeds.get(name, servo.max_speed_m_s)
            goals[name] = (_goal_steps(servo, length), _speed_units(servo, speed))
        self._sync_write_goals(goals)
        return {name: steps for name, (steps, _) in goals.items()}

    def hold(self) -> list[ServoState]:
        """Safe state: enable torque and make each present position the goal.

        Fault bits do not stop this (it is what a fault handler calls). Each servo is read on
        its own, so one that does not answer (a bulk read would stall at it) leaves the others
        held; its :class:`ServoCommError` is raised after them. Returns the states read,
        faults included.
        """
        self._release_port()
        states, failed = [], []
        for servo in self.config.servo:
            try:
                states.append(self._read_one(servo))
            except ServoCommError as exc:
                failed.append(exc)
        goals = {}
        for state in states:
            servo = self.servos[state.name]
            goals[state.name] = (state.position_steps, _speed_units(servo, servo.max_speed_m_s))
        self._sync_write_goals(goals)
        for state in states:
            servo = self.servos[state.name]
            result, _ = self.packets.write1ByteTxRx(self.port, servo.id, mx12.Addr.TORQUE_ENABLE, 1)
            self._check(servo, result, 0, "write torque enable")
        if failed:
            raise failed[0]
        return states

    def read_hold(self, name: str) -> tuple[bool, int, ServoState]:
        """Read back whether one servo holds: torque enabled, goal position (steps), its state.

        Raises
        ------
        ServoCommError
            The servo did not answer or the answer was corrupt.
        """
        servo = self.servos[name]
        self._release_port()
        n = mx12.Addr.PRESENT_LOAD + 2 - mx12.Addr.TORQUE_ENABLE
        data, result, error = self.packets.readTxRx(self.port, servo.id, mx12.Addr.TORQUE_ENABLE, n)
        self._check(servo, result, 0, "read torque enable/goal/present")
        goal = mx12.int16_from_word(data[6] | data[7] << 8)  # GOAL_POSITION = TORQUE_ENABLE + 6
        present = data[mx12.Addr.PRESENT_POSITION - mx12.Addr.TORQUE_ENABLE :]
        return bool(data[0]), goal, self._state(servo, present, error, time.monotonic_ns())

    # --- read back ----------------------------------------------------------------------------
    def read_states(self) -> list[ServoState]:
        """Read position, speed and load of every servo (configuration order).

        Raises
        ------
        ServoFaultError
            A servo's error byte was non-zero (``states`` holds everything read).
        ServoCommError
            A servo did not answer or the answer was corrupt.
        """
        states = self._read_all()
        for state in states:
            if state.faults:
                raise ServoFaultError(
                    f"servo '{state.name}' (ID {state.servo_id}) reports: "
                    f"{', '.join(state.faults)}",
                    state.servo_id,
                    state.faults,
                    states,
                )
        return states

    def read_lengths(self) -> dict[str, float]:
        """Present string lengths, name -> m."""
        return {s.name: s.length_m for s in self.read_states()}

    # --- internals ----------------------------------------------------------------------------
    def _release_port(self) -> None:
        """Clear the SDK's busy flag: a transaction cut short by an exception (a port gone, in
        another thread) leaves it set, and every later one would fail as "Port is in use"."""
        self.port.is_using = False

    def _by_name(self, values, what: str) -> dict[str, float]:
        if isinstance(values, Mapping):
            unknown = set(values) - set(self.servos)
            if unknown:
                raise ServoLimitError(f"{what}: unknown servo(s) {sorted(unknown)}")
            return {name: float(v) for name, v in values.items()}
        values = list(values)
        if len(values) != len(self.config.servo):
            raise ServoLimitError(
                f"{what}: {len(values)} values for {len(self.config.servo)} servos"
            )
        return {s.name: float(v) for s, v in zip(self.config.servo, values, strict=True)}

    def _sync_write_goals(self, goals: dict[str, tuple[int, int]]) -> None:
        group = sdk.GroupSyncWrite(self.port, self.packets, mx12.Addr.GOAL_POSITION, 4)
        for name, (steps, speed) in goals.items():
            word = mx12.word_from_int16(steps)
            group.addParam(self.servos[name].id, [word & 0xFF, word >> 8, speed & 0xFF, speed >> 8])
        if self.port.in_reply_wait:
            group.makeParam()
            self.port.write_packet(_sync_write_packet(mx12.Addr.GOAL_POSITION, 4, group.param))
            self.goals_sent_ns = self.port.written_ns
            return
        result = group.txPacket()
        self.goals_sent_ns = self.port.written_ns
        if result != sdk.COMM_SUCCESS:
            raise ServoCommError(
                f"servo bus {self.config.port}: sync write of goals failed: "
                f"{self.packets.getTxRxResult(result)}",
                sdk.BROADCAST_ID,
                result,
            )

    def _read_all(self) -> list[ServoState]:
        if self.config.read_mode == "bulk":
            raw = self._bulk_read(mx12.Addr.PRESENT_POSITION, STATE_BYTES)
            return [self._state(self.servos[name], *raw[name]) for name in raw]
        return [self._read_one(servo) for servo in self.config.servo]

    def _read_one(self, servo: ServoConfig) -> ServoState:
        data, result, error = self.packets.readTxRx(
            self.port, servo.id, mx12.Addr.PRESENT_POSITION, STATE_BYTES
        )
        self._check(servo, result, 0, "read present position/speed/load")
        # the servo samples between our request and its reply
        return self._state(servo, data, error, (self.port.written_ns + time.monotonic_ns()) // 2)

    def _bulk_read(self, addr: int, n: int) -> dict[str, tuple[list[int], int, int]]:
        group = sdk.GroupBulkRead(self.port, self.packets)
        for servo in self.config.servo:
            group.addParam(servo.id, addr, n)
        group.makeParam()
        result = self.packets.bulkReadTx(self.port, group.param, 3 * len(self.config.servo))
        sent_ns = self.port.written_ns  # every servo samples on the one request, just after it
        if result != sdk.COMM_SUCCESS:
            self._check(self.config.servo[0], result, 0, "bulk read request")
        raw = {}
        for servo in self.config.servo:
            data, result, error = self.packets.readRx(self.port, servo.id, n)
            self._check(servo, result, 0, "bulk read reply")
            raw[servo.name] = (data, error, sent_ns)
        return raw

    def _state(self, servo: ServoConfig, data: list[int], error: int, t_ns: int) -> ServoState:
        position = mx12.int16_from_word(data[0] | data[1] << 8)
        speed_units = mx12.signed_from_sign_magnitude(data[2] | data[3] << 8)
        load_units = mx12.signed_from_sign_magnitude(data[4] | data[5] << 8)
        return ServoState(
            name=servo.name,
            servo_id=servo.id,
            position_steps=position,
            length_m=mx12.steps_to_length(servo, position),
            speed_m_s=servo.length_sign * speed_units * mx12.string_speed_per_unit(servo),
            load_fraction=load_units * mx12.LOAD_UNIT,
            faults=mx12.fault_names(error),
            t_ns=t_ns,
        )

    def _check(self, servo: ServoConfig, result: int, error: int, what: str) -> None:
        where = f"servo '{servo.name}' (ID {servo.id}) on {self.config.port}"
        if result == sdk.COMM_RX_TIMEOUT:
            text = self.packets.getTxRxResult(result)
            why = f"{where}: {what}: {text} (none within {self.reply_timeout_s:g} s)"
            raise ServoTimeoutError(why, servo.id, result)
        if result != sdk.COMM_SUCCESS:
            raise ServoCommError(
                f"{where}: {what}: {self.packets.getTxRxResult(result)}", servo.id, result
            )
        if error:
            faults = mx12.fault_names(error)
            raise ServoFaultError(f"{where}: {what}: {', '.join(faults)}", servo.id, faults)


def _sync_write_packet(addr: int, n: int, param: list[int]) -> bytes:
    """A Protocol 1.0 SYNC WRITE to every servo: header, broadcast ID, length, instruction,
    start address, bytes per servo, ``param`` (ID and ``n`` bytes per servo), checksum (the
    inverted low byte of the sum from the ID on)."""
    body = [sdk.BROADCAST_ID, len(param) + 4, sdk.INST_SYNC_WRITE, addr, n, *param]
    return bytes([0xFF, 0xFF, *body, ~sum(body) & 0xFF])


def _check_config_limits(servo: ServoConfig) -> None:
    """The configured length range must map into the multi-turn range; a speed unit must fit."""
    for length in (servo.min_length_m, servo.max_length_m):
        steps = mx12.length_to_steps(servo, length)
        if abs(steps) > MX_POSITION_LIMIT:
            raise ServoLimitError(
                f"servo '{servo.name}' (ID {servo.id}): length limit {length} m maps to "
                f"position {steps:.0f}, outside +-{MX_POSITION_LIMIT} steps"
            )
    if servo.max_speed_m_s < mx12.string_speed_per_unit(servo):
        raise ServoLimitError(
            f"servo '{servo.name}' (ID {servo.id}): max_speed_m_s {servo.max_speed_m_s} is below "
            f"one speed unit ({mx12.string_speed_per_unit(servo):.2e} m/s)"
        )


def _goal_steps(servo: ServoConfig, length_m: float) -> int:
    """The goal position of a string length: a length within ``LENGTH_ROUNDING_M`` outside the
    limit is taken as the limit, and the position is rounded to the step nearest the length
    whose length is still within the limit."""
    where = f"servo '{servo.name}' (ID {servo.id})"
    lo, hi = servo.min_length_m, servo.max_length_m
    if not math.isfinite(length_m):
        raise ServoLimitError(f"{where}: string length {length_m} m is not finite")
    if not lo - LENGTH_ROUNDING_M <= length_m <= hi + LENGTH_ROUNDING_M:
        raise ServoLimitError(
            f"{where}: string length {length_m:.4f} m is outside the limit [{lo}, {hi}] m"
        )
    length_m = min(max(length_m, lo), hi)
    exact = mx12.length_to_steps(servo, length_m)
    steps = round(exact)
    if not lo <= mx12.steps_to_length(servo, steps) <= hi:  # half a step past a limit
        steps = math.floor(exact) if steps > exact else math.ceil(exact)
    return int(steps)


def _speed_units(servo: ServoConfig, speed_m_s: float) -> int:
    """Moving speed units for a string speed; never 0 (which the MX reads as 'no limit')."""
    where = f"servo '{servo.name}' (ID {servo.id})"
    if not (math.isfinite(speed_m_s) and 0.0 < speed_m_s <= servo.max_speed_m_s):
        raise ServoLimitError(
            f"{where}: string speed {speed_m_s} m/s is outside the limit "
            f"(0, {servo.max_speed_m_s}] m/s"
        )
    units = math.floor(speed_m_s / mx12.string_speed_per_unit(servo))
    return min(max(units, 1), mx12.SPEED_MAX_UNITS)
