"""Emulated wheel board (ATmega2560, four gimbal-motor speed loops) on a pseudo-terminal.

The device side of the wheel-board protocol (docs/protocol.md), with the codec of
:mod:`gyrohost.drivers.wheelproto`. Like the firmware it runs a 1 kHz control tick, counted
from boot on the emulator's clock, so simulated-time runs are exact:

- receiver rules: frames longer than 44 bytes, bad COBS, short frames and bad CRCs are dropped and
  counted; an unknown id or a device-to-host id, or a wrong payload length, gets an ERROR reply;
  only a control frame (HEARTBEAT, SET_SPEEDS, STOP_ALL) with a good CRC restarts the heartbeat
  timer, queries do not;
- HELLO, SET_SPEEDS (whole message refused above SPEED_MAX or while a blocking fault is latched),
  STOP_ALL, PARAM_GET/SET (range, BUSY for MODE/POLE_PAIRS while outputs are on), PARAM_SAVE (ACK
  after 300 ticks, SAVING status meanwhile), PARAM_DEFAULTS, CLEAR_FAULTS (the bits of its mask),
  GET_STATS; CALIBRATE_ENC is answered with an ACK at once, the offset unchanged (no electrical
  model);
- EEPROM: the board comes calibrated, unless ``blank_eeprom``: it then boots as a new board,
  defaults with PARAMS_DEFAULTED latched, and refuses a nonzero closed-loop setpoint of a wheel
  with OFFSET_UNCALIBRATED until CALIBRATE_ENC or a PARAM_SET of its ENC_OFFSET (PARAM_DEFAULTS
  makes all four uncalibrated again); after a PARAM_SAVE it boots from the saved image;
- open loop (MODE 1, never restored at boot): OPEN_LOOP_LIMIT after ``OPEN_LOOP_MS`` of a wheel
  running, then as the fail-safe;
- fail-safe: no control frame for HEARTBEAT_MS latches HEARTBEAT_LOST (frames that came while the
  emulator was held up are placed among its catch-up ticks by ``PtyDevice.poll``: the emulator's
  delay is not the host's silence), all targets become 0 and the setpoints ramp down at
  DECEL_RAD_S2 (ACCEL_RAD_S2 otherwise; both are mrad/s per tick); a wheel ramped to rest brakes
  on until its encoder shows it stopped (the count difference over the last ``STOP_WINDOW``
  ticks, in the direction being braked, below ``STOP_RAD_S`` as a mean; at most
  ``STOP_TICKS``);
- TELEMETRY every TELEMETRY_DIV ticks: control-step time, sequence number, speeds, drive levels,
  status and fault word; a frame leaves when its bits have crossed the wire at the link's baud
  (replies go at once, behind the frames already on the wire);
- each tick runs in the firmware's order: the wheels turn under the last tick's drive, the
  encoder is read, the setpoints ramp.

Motor model (not the firmware's): while a wheel's outputs are enabled its true speed follows the
ramped setpoint with a first-order lag (``time_constant_s``); with outputs off it coasts down
(``coast_time_constant_s``). A driven wheel's speed errs from that lag by a first-order
Gauss-Markov process of stationary std ``speed_error_std_rad_s`` and the motor's time constant:
the torque the speed loop does not cancel (cogging, the bars' gyroscopic reaction, the loop
acting on its own quantised estimate) through the motor's response. Without it a wheel holds its
speed exactly and its encoder walks a fixed quantisation pattern, whose noise averages out like
no real encoder's. An optional ripple multiplies the true speed by
``1 + ripple_fraction * sin(ripple_per_rev * angle)``. The reported speed is measured as the
firmware measures it (``speed.h``): each tick the wheel angle is read as a 14-bit encoder count, the
count difference to the last tick (wrapped at 14 bits) is the raw speed, and the firmware's
low-pass (1/2^SPEED_FILTER_SHIFT per tick) filters it; the first tick after a boot or a skipped
stretch of ticks only primes the encoder (estimate held). So the telemetry carries the real
quantisation noise (one count per tick is 0.38 rad/s raw; about 0.014 rad/s RMS after the
low-pass at SPEED_FILTER_SHIFT 3). In open loop the reported speed is the setpoint.
The drive level is the PI's proportional part, clipped to DRIVE_MAX (no electrical model).

Run-time fault: :meth:`WheelBoardEmulator.reset` reboots the board (optionally after ``down_s``
seconds of silence): parameters reload from the last PARAM_SAVE, the tick counter, ``t_us`` and
``seq`` restart at 0, faults clear (WATCHDOG_RESET set for a watchdog reset), targets and
setpoints are 0; the wheels keep spinning and coast down.
"""

import math
import random
from collections import deque

from gyrohost.drivers import wheelproto as wp
from gyrohost.simrig.config import WheelEmuConfig
from gyrohost.simrig.faults import FaultFilter
from gyrohost.simrig.pty_link import PtyDevice

FW_MAJOR, FW_MINOR = 1, 0
SAVE_TICKS = 300
"""Ticks an EEPROM save takes (one 84-byte slot, about 3.3 ms a byte)."""
ENCODER_COUNTS = 1 << 14
"""Counts per turn of the AS5048A (14 bits)."""
RAD_PER_COUNT = 2.0 * math.pi / ENCODER_COUNTS
OPEN_LOOP_MS = 10_000
"""Longest open-loop run without a stop, as the firmware's APP_OPEN_LOOP_MS."""
_CONTROL_FRAMES = ("HEARTBEAT", "SET_SPEEDS", "STOP_ALL")
"""Frames that restart the heartbeat timer, as in the firmware (app_is_control_frame)."""
MAX_CATCH_UP_TICKS = 1000
"""More ticks than this behind (a stalled emulator loop) are skipped and counted as overruns."""
STOP_RAD_S = 0.5
"""A wheel ramped to rest brakes in closed loop while the encoder's mean speed over the last
``STOP_WINDOW`` ticks, in the direction of the (lagging) filtered estimate, is this or more (the
firmware's ``APP_STOP_Q8``), for at most ``STOP_TICKS`` ticks (``APP_STOP_TICKS``)."""
STOP_WINDOW = 4
"""Ticks of the stop's speed (the firmware's ``APP_STOP_WINDOW``: robust to encoder noise)."""
STOP_TICKS = 500

_P = {p.name: p.id for p in wp.PARAMS}
_FAULT_BIT = {name: 1 << bit for bit, (name, _) in wp.FAULTS.items()}
_STATUS_BIT = {name: 1 << bit for bit, (name, _) in wp.STATUS.items()}
_ERROR_CODE = {name: code for code, (name, _) in wp.ERRORS.items()}
_BLOCKING = sum(_FAULT_BIT[n] for n in wp.BLOCKING_FAULTS)
_FORCED_TO_ZERO = _FAULT_BIT["HEARTBEAT_LOST"] | _FAULT_BIT["OPEN_LOOP_LIMIT"]
_STATS_FIELDS = wp.BY_NAME["STATS"].fields
_ENC_OFFSET_IDS = [_P[f"ENC_OFFSET_M{i}"] for i in range(wp.N_WHEELS)]


def _defaults() -> dict[int, int]:
    """Every parameter at its default: id -> value."""
    return {p.id: p.default for p in wp.PARAMS}


def ramp_step(value: int, target: int, step: int) -> int:
    """Move ``value`` toward ``target`` by at most ``step`` (all mrad/s), as ``ramp.cpp``."""
    step = max(step, 1)
    if target > value:
        return min(value + step, target)
    return max(value - step, target)


class WheelBoardEmulator(PtyDevice):
    """Wheel-board emulator; see the module docstring.

    Parameters
    ----------
    emu : WheelEmuConfig, optional
        Motor response, ripple and stream faults.

    Attributes
    ----------
    omega_rad_s : list of float, len 4, rad/s
        True wheel speeds (what the truth model spins), ripple included.
    boots : int
        Number of boots so far (1 after construction).
    telemetry_sent : int
        TELEMETRY frames sent since construction (over all boots; a frame is sent once its
        bits have crossed the wire).
    """

    FRAME_END = 0  # COBS: every frame ends in 0x00

    def __init__(self, emu: WheelEmuConfig | None = None, baud: int = 1_000_000) -> None:
        emu = emu if emu is not None else WheelEmuConfig()
        super().__init__(FaultFilter(emu.faults))
        self.emu = emu
        self.telemetry_wire_s = wp.wire_time_s("TELEMETRY", baud)
        self._on_wire: deque[tuple[float, bytes]] = deque()  # (last byte's time, telemetry)
        # the EEPROM's parameter image; None: no valid slot
        self.saved = None if emu.blank_eeprom else _defaults()
        self.omega_rad_s = [0.0] * wp.N_WHEELS
        self.angle_rad = [0.0] * wp.N_WHEELS
        self._base_rad_s = [0.0] * wp.N_WHEELS
        self._rng = random.Random(emu.seed)
        self.boots = 0
        self.telemetry_sent = 0
        self._reset_request: tuple[float, bool] | None = None
        self._down_until_s: float | None = None
        self._down_last_s = 0.0
        self._watchdog = False
        self._boot_s: float | None = None
        self._t_s = 0.0
        self._boot(boot_faults=0)

    # --- boot and run-time faults -------------------------------------------------------------
    def _boot(self, boot_faults: int) -> None:
        self.params = _defaults() if self.saved is None else dict(self.saved)
        # wheels whose ENC_OFFSET is a default that fits no motor, as the firmware's uncal_mask
        self._uncalibrated = set() if self.saved is not None else set(range(wp.N_WHEELS))
        if self.saved is None:
            boot_faults |= _FAULT_BIT["PARAMS_DEFAULTED"]
        self.params[_P["MODE"]] = 0  # as the firmware: open loop is enabled per session
        self._open_ms = 0
        self.fault_word = boot_faults
        self.stats = dict.fromkeys(_STATS_FIELDS, 0)
        self.ticks = 0
        self.seq = 0
        self._telem_count = 0
        self._since_host_ms = 0
        self._stopping = False
        self._save_done_tick: int | None = None
        self.targets = [0] * wp.N_WHEELS
        self.setpoints = [0] * wp.N_WHEELS
        self.measured = [0.0] * wp.N_WHEELS
        self._last_count: list[int | None] = [None] * wp.N_WHEELS  # None: encoder not primed
        self._raw_rad_s: list[float | None] = [None] * wp.N_WHEELS  # last tick's count difference
        self.drive = [0] * wp.N_WHEELS
        self.enabled = [False] * wp.N_WHEELS
        self._stop_ticks = [0] * wp.N_WHEELS
        self._stop_raw: list[list[float | None]] = [[] for _ in range(wp.N_WHEELS)]
        self._rx = bytearray()
        self._rx_overflow = False
        self.boots += 1

    def reset(self, down_s: float = 0.0, watchdog: bool = False) -> None:
        """Reboot the board: silent and deaf for ``down_s`` s, then a fresh boot.

        Parameters
        ----------
        down_s : float, s
            Time before the new boot (bootloader, brown-out); 0 reboots at the next tick.
        watchdog : bool
            The reset was a watchdog reset: the new boot latches WATCHDOG_RESET.
        """
        with self.lock:
            self._reset_request = (down_s, watchdog)

    def rest(self) -> None:
        """Every wheel at rest at once, targets and setpoints 0 (the rig put back by hand)."""
        with self.lock:
            self._reset_wheels()
            self.omega_rad_s = [0.0] * wp.N_WHEELS
            self._base_rad_s = [0.0] * wp.N_WHEELS
            self.measured = [0.0] * wp.N_WHEELS
            self.enabled = [False] * wp.N_WHEELS

    def wheel_speeds_rad_s(self, at_s: float | None = None) -> list[float]:
        """True wheel speeds, rad/s (a copy, taken under the lock): at the last tick, or
        carried on from it to the emulator time ``at_s`` s by the motors' lag (or coast),
        without the speed error's next increment: the truth's steps end between the ticks."""
        with self.lock:
            if at_s is None or self._boot_s is None:
                return list(self.omega_rad_s)
            dt_s = max(at_s - self._state_s(), 0.0)
            return [self._relaxed(i, dt_s) * self._ripple_factor(i) for i in range(wp.N_WHEELS)]

    def _state_s(self) -> float:
        """The emulator time the wheels' state is at, s: the last tick's, or the last coast's
        while down."""
        if self._down_until_s is not None:
            return self._down_last_s
        return self._boot_s + self.ticks / wp.TICK_HZ

    # --- PtyDevice hooks ----------------------------------------------------------------------
    @property
    def next_send_s(self) -> float | None:
        """When the next telemetry frame's last byte has crossed the wire, s (None while none
        is due): the rig's loop wakes then, so that it reaches the host as the wire makes it."""
        if self._on_wire:
            return self._on_wire[0][0]
        div = self.params[_P["TELEMETRY_DIV"]]
        if self._boot_s is None or self._down_until_s is not None or div == 0:
            return None
        tick = self.ticks + max(div - self._telem_count, 1)
        return self._boot_s + tick / wp.TICK_HZ + self.telemetry_wire_s

    def tick(self, now_s: float) -> None:
        self._ticks_to(now_s)
        self._release(now_s)

    def _release(self, until_s: float) -> None:
        """Send, in order, the telemetry frames on the wire whose last byte is due by
        ``until_s``, s."""
        while self._on_wire and self._on_wire[0][0] <= until_s:
            self.send(self._on_wire.popleft()[1], self._t_s)
            self.telemetry_sent += 1

    def _ticks_to(self, now_s: float) -> None:
        self._t_s = now_s
        if self._down(now_s):
            return
        if self._boot_s is None:
            self._boot_s = now_s
        due = int((now_s - self._boot_s) * wp.TICK_HZ + 1e-9)
        missed = due - self.ticks - MAX_CATCH_UP_TICKS
        if missed > 0:
            self.ticks += missed
            self.stats["tick_overruns"] = min(self.stats["tick_overruns"] + missed, 0xFFFF)
            self.fault_word |= _FAULT_BIT["TICK_OVERRUN"]
            self._physics(missed / wp.TICK_HZ)
            self._last_count = [None] * wp.N_WHEELS  # a long gap re-primes, as speed.h
        while self.ticks < due:
            self.ticks += 1
            self._control_tick()

    def _down(self, now_s: float) -> bool:
        """Start a requested reset, coast while down, boot when due; True while down."""
        if self._reset_request is not None:
            down_s, self._watchdog = self._reset_request
            self._reset_request = None
            self._down_until_s = now_s + down_s
            self._down_last_s = now_s
            self._on_wire.clear()  # the UART's bytes in flight are lost
            self.enabled = [False] * wp.N_WHEELS
        if self._down_until_s is None:
            return False
        self._physics(max(now_s - self._down_last_s, 0.0))
        self._down_last_s = now_s
        if now_s < self._down_until_s:
            return True
        self._down_until_s = None
        self._boot(_FAULT_BIT["WATCHDOG_RESET"] if self._watchdog else 0)
        self._boot_s = now_s
        return False

    def handle_rx(self, data: bytes, now_s: float) -> None:
        self._t_s = now_s
        if self._down_until_s is not None or self._reset_request is not None:
            return  # rebooting: bytes are lost
        for byte in data:
            if byte:
                if len(self._rx) < wp.MAX_ENCODED:
                    self._rx.append(byte)
                else:
                    self._rx_overflow = True
                continue
            frame, overflow = bytes(self._rx), self._rx_overflow
            self._rx.clear()
            self._rx_overflow = False
            if overflow:
                self._count("oversize")
            elif frame:
                self._receive(frame)

    # --- receiver and dispatcher --------------------------------------------------------------
    def _count(self, name: str) -> None:
        self.stats[name] = min(self.stats[name] + 1, 0xFFFF)

    def _receive(self, frame: bytes) -> None:
        msg = None
        try:
            msg = wp.decode_frame(frame)
            msg_id = msg.id
        except wp.FrameError as exc:
            if exc.kind not in ("unknown_id", "bad_length"):
                self._count(exc.kind)
                return
            raw = wp.cobs_decode(frame)  # the CRC was good: id and length are known
            msg_id, payload_len = raw[0], len(raw) - 3
        if msg is not None and msg.name in _CONTROL_FRAMES:
            self._since_host_ms = 0  # the host's control thread is alive; queries count not
        spec = wp.BY_ID.get(msg_id)
        if spec is None or spec.direction != "H2D":
            self._count("unknown_id")
            self._error(msg_id, "UNKNOWN_MESSAGE", msg_id)
        elif msg is None:
            self._count("bad_length")
            self._error(msg_id, "BAD_LENGTH", payload_len)
        else:
            getattr(self, f"_on_{msg.name.lower()}")(msg.fields)

    def _send_msg(self, name: str, **fields: int) -> None:
        """Send a reply at once, behind the telemetry frames already on the wire (the UART's
        order: a fault latched before a CLEAR_FAULTS shows in no frame after its ACK); those
        then leave a little early, and only around requests."""
        self._release(math.inf)
        self.send(wp.encode(name, **fields), self._t_s)

    def _error(self, req_id: int, name: str, detail: int) -> None:
        self._send_msg("ERROR", req_id=req_id, code=_ERROR_CODE[name], detail=detail & 0xFF)

    def _ack(self, name: str) -> None:
        self._send_msg("ACK", req_id=wp.BY_NAME[name].id)

    def _on_hello(self, _fields: dict) -> None:
        self._send_msg(
            "HELLO_REPLY",
            proto_version=wp.PROTO_VERSION,
            fw_major=FW_MAJOR,
            fw_minor=FW_MINOR,
            n_wheels=wp.N_WHEELS,
            n_params=len(wp.PARAMS),
            tick_hz=wp.TICK_HZ,
        )

    def _on_heartbeat(self, _fields: dict) -> None:
        pass  # receiving it restarted the timer

    def _on_set_speeds(self, fields: dict) -> None:
        if self.fault_word & _BLOCKING:
            self._error(wp.BY_NAME["SET_SPEEDS"].id, "FAULT_ACTIVE", 0)
            return
        vmax = self.params[_P["SPEED_MAX_MRAD_S"]]
        closed_loop = self.params[_P["MODE"]] == 0
        speeds = [fields[f"w{i}_mrad_s"] for i in range(wp.N_WHEELS)]
        for i, value in enumerate(speeds):
            if abs(value) > vmax:
                self._error(wp.BY_NAME["SET_SPEEDS"].id, "SETPOINT_ABOVE_MAX", i)
                return
            if value and closed_loop and i in self._uncalibrated:
                self._error(wp.BY_NAME["SET_SPEEDS"].id, "OFFSET_UNCALIBRATED", i)
                return
        self.targets = speeds
        self._stopping = False

    def _on_stop_all(self, _fields: dict) -> None:
        self.targets = [0] * wp.N_WHEELS
        self._stopping = True
        self._ack("STOP_ALL")

    def _on_param_get(self, fields: dict) -> None:
        pid = fields["param_id"]
        if pid in wp.PARAM_BY_ID:
            self._send_msg("PARAM_VALUE", param_id=pid, value=self.params[pid])
        else:
            self._error(wp.BY_NAME["PARAM_GET"].id, "UNKNOWN_PARAM", pid)

    def _on_param_set(self, fields: dict) -> None:
        pid, value = fields["param_id"], fields["value"]
        req = wp.BY_NAME["PARAM_SET"].id
        structural = pid in (_P["MODE"], _P["POLE_PAIRS"])
        if (structural and any(self.enabled)) or self._save_done_tick is not None:
            self._error(req, "BUSY", pid)
        elif pid not in wp.PARAM_BY_ID:
            self._error(req, "UNKNOWN_PARAM", pid)
        elif not wp.PARAM_BY_ID[pid].min <= value <= wp.PARAM_BY_ID[pid].max:
            self._error(req, "PARAM_OUT_OF_RANGE", pid)
        else:
            self.params[pid] = value
            if pid in _ENC_OFFSET_IDS:
                self._uncalibrated.discard(_ENC_OFFSET_IDS.index(pid))
            if structural:
                self._reset_wheels()
            self._send_msg("PARAM_VALUE", param_id=pid, value=value)

    def _on_param_save(self, _fields: dict) -> None:
        if self._save_done_tick is not None:
            self._error(wp.BY_NAME["PARAM_SAVE"].id, "BUSY", 0)
        else:
            self._save_done_tick = self.ticks + SAVE_TICKS

    def _on_param_defaults(self, _fields: dict) -> None:
        if any(self.enabled) or self._save_done_tick is not None:
            self._error(wp.BY_NAME["PARAM_DEFAULTS"].id, "BUSY", 0)
            return
        self.params = _defaults()
        self._uncalibrated = set(range(wp.N_WHEELS))
        self._reset_wheels()
        self._ack("PARAM_DEFAULTS")

    def _on_clear_faults(self, fields: dict) -> None:
        self.fault_word &= ~fields["mask"]
        if fields["mask"] & _FAULT_BIT["HEARTBEAT_LOST"]:
            self._since_host_ms = 0
        self._ack("CLEAR_FAULTS")

    def _on_calibrate_enc(self, fields: dict) -> None:
        req = wp.BY_NAME["CALIBRATE_ENC"].id
        if fields["wheel"] >= wp.N_WHEELS:
            self._error(req, "CALIBRATION_FAILED", 6)  # BAD_WHEEL
        elif any(self.enabled) or any(self.targets) or self._save_done_tick is not None:
            self._error(req, "BUSY", fields["wheel"])
        else:
            self._uncalibrated.discard(fields["wheel"])
            self._ack("CALIBRATE_ENC")

    def _on_get_stats(self, _fields: dict) -> None:
        self._send_msg("STATS", **self.stats)

    def _reset_wheels(self) -> None:
        self.targets = [0] * wp.N_WHEELS
        self.setpoints = [0] * wp.N_WHEELS
        self.drive = [0] * wp.N_WHEELS

    # --- control tick -------------------------------------------------------------------------
    def _control_tick(self) -> None:
        """One 1 kHz tick in the firmware's order: the wheels have turned under the last tick's
        drive (a setpoint acts from the tick that set it on, never before the frame that asked
        for it), the encoder is read, then the setpoints ramp and the drive is set."""
        self._physics(1.0 / wp.TICK_HZ)
        p = self.params
        self._since_host_ms = min(self._since_host_ms + 1, 0xFFFF)
        if self._since_host_ms >= p[_P["HEARTBEAT_MS"]]:
            self.fault_word |= _FAULT_BIT["HEARTBEAT_LOST"]
        running = any(self.setpoints) or any(self.targets)
        self._open_ms = self._open_ms + 1 if p[_P["MODE"]] == 1 and running else 0
        if self._open_ms >= OPEN_LOOP_MS:
            self.fault_word |= _FAULT_BIT["OPEN_LOOP_LIMIT"]
        failsafe = bool(self.fault_word & _FORCED_TO_ZERO)
        step = p[_P["DECEL_RAD_S2"]] if failsafe or self._stopping else p[_P["ACCEL_RAD_S2"]]
        for i in range(wp.N_WHEELS):
            if failsafe:
                self.targets[i] = 0  # never resumes by itself after a clear
            self.setpoints[i] = ramp_step(self.setpoints[i], self.targets[i], step)
            self.enabled[i] = self._drives(i)
        self._measure()
        if self._save_done_tick is not None and self.ticks >= self._save_done_tick:
            self._save_done_tick = None
            self.saved = dict(self.params)
            self._ack("PARAM_SAVE")
        self._telemetry()

    def _drives(self, i: int) -> bool:
        """Whether wheel ``i`` is driven this tick: as the firmware, a wheel ramped to rest keeps
        braking until it has (nearly) stopped, and a wheel that is off stays off."""
        if self.setpoints[i] != 0 or self.targets[i] != 0:
            self._stop_ticks[i] = 0
            return True
        if not self.enabled[i] or self._stop_ticks[i] >= STOP_TICKS:
            return False
        self._stop_ticks[i] += 1
        window = self._stop_raw[i]
        if self._stop_ticks[i] == 1:
            window.clear()  # the first braking tick only takes the angle, as the firmware
            return True
        window.append(self._raw_rad_s[i])
        del window[:-STOP_WINDOW]
        if len(window) < STOP_WINDOW or None in window:
            return True
        mean = sum(w for w in window if w is not None) / STOP_WINDOW
        # the filtered estimate lags the braking: its sign is the direction being braked
        return (mean if self.measured[i] >= 0 else -mean) >= STOP_RAD_S

    def _physics(self, dt_s: float) -> None:
        emu = self.emu
        # the exact step of the Gauss-Markov error: its stationary variance is kept
        on = math.exp(-dt_s / emu.time_constant_s)
        error_std = emu.speed_error_std_rad_s * math.sqrt(1.0 - on * on)
        for i in range(wp.N_WHEELS):
            base = self._relaxed(i, dt_s)
            if self.enabled[i] and error_std:
                base += self._rng.gauss(0.0, error_std)
            self._base_rad_s[i] = base
            omega = base * self._ripple_factor(i)
            # the angle turned is the step's mean speed (trapezoid): an encoder's count
            # difference is the last tick's mean speed, half a tick behind its end's
            mean_rad_s = 0.5 * (self.omega_rad_s[i] + omega)
            self.omega_rad_s[i] = omega
            self.angle_rad[i] = (self.angle_rad[i] + mean_rad_s * dt_s) % (2 * math.pi)

    def _relaxed(self, i: int, dt_s: float) -> float:
        """Wheel ``i``'s speed without ripple ``dt_s`` s on, rad/s: its lag towards the held
        setpoint while driven, its coast otherwise (the speed error's increment aside)."""
        base, emu = self._base_rad_s[i], self.emu
        if not self.enabled[i]:
            return base * math.exp(-dt_s / emu.coast_time_constant_s)
        setpoint = self.setpoints[i] / 1000.0
        return setpoint + (base - setpoint) * math.exp(-dt_s / emu.time_constant_s)

    def _ripple_factor(self, i: int) -> float:
        emu = self.emu
        return 1.0 + emu.ripple_fraction * math.sin(emu.ripple_per_rev * self.angle_rad[i])

    def _measure(self) -> None:
        p = self.params
        open_loop = p[_P["MODE"]] == 1
        gain = 1.0 / (1 << p[_P["SPEED_FILTER_SHIFT"]])
        drive_max = p[_P["DRIVE_MAX_Q15"]]
        for i in range(wp.N_WHEELS):
            raw_rad_s = self._encoder_speed(i)
            self._raw_rad_s[i] = raw_rad_s
            if open_loop:
                self.measured[i] = self.setpoints[i] / 1000.0 if self.enabled[i] else 0.0
                cap = min(p[_P["OPEN_LOOP_DRIVE_Q15"]], drive_max)
                drive = cap if self.enabled[i] else 0
                self.drive[i] = int(math.copysign(drive, self.setpoints[i]))
                continue
            if raw_rad_s is not None:
                self.measured[i] += (raw_rad_s - self.measured[i]) * gain
            error_rad_s = self.setpoints[i] / 1000.0 - self.measured[i]
            error_counts_per_tick = error_rad_s / wp.TICK_HZ / RAD_PER_COUNT  # KP's unit
            drive = int(p[_P["KP"]] * error_counts_per_tick) if self.enabled[i] else 0
            self.drive[i] = max(-drive_max, min(drive, drive_max))

    def _encoder_speed(self, i: int) -> float | None:
        """Read wheel ``i``'s encoder: the count difference to the last tick as a speed, rad/s
        (None on the priming read)."""
        count = int(self.angle_rad[i] / RAD_PER_COUNT) % ENCODER_COUNTS
        last, self._last_count[i] = self._last_count[i], count
        if last is None:
            return None
        delta = (count - last + ENCODER_COUNTS // 2) % ENCODER_COUNTS - ENCODER_COUNTS // 2
        return delta * RAD_PER_COUNT * wp.TICK_HZ

    def status(self) -> int:
        """The TELEMETRY status byte now."""
        p = self.params
        s = _STATUS_BIT["OUTPUTS_ENABLED"] if any(self.enabled) else 0
        if p[_P["MODE"]] == 1:
            s |= _STATUS_BIT["OPEN_LOOP"]
        if self.fault_word & _FAULT_BIT["HEARTBEAT_LOST"]:
            s |= _STATUS_BIT["FAILSAFE"]
        if self._save_done_tick is not None:
            s |= _STATUS_BIT["SAVING"]
        for i in range(wp.N_WHEELS):
            if self.enabled[i] and abs(self.drive[i]) >= p[_P["DRIVE_MAX_Q15"]]:
                s |= _STATUS_BIT[f"SATURATED_M{i}"]
        return s

    def _telemetry(self) -> None:
        div = self.params[_P["TELEMETRY_DIV"]]
        if div == 0:
            return
        self._telem_count += 1
        if self._telem_count < div:
            return
        self._telem_count = 0
        fields = {
            "t_us": (self.ticks * 1000) & 0xFFFFFFFF,
            "seq": self.seq,
            "status": self.status(),
            "faults": self.fault_word,
        }
        for i in range(wp.N_WHEELS):
            fields[f"w{i}_mrad_s"] = int(self.measured[i] * 1000.0)  # toward zero, as speed.h
            fields[f"d{i}_q15"] = self.drive[i]
        self.seq = (self.seq + 1) & 0xFFFF
        # taken at its tick, whole for the host once its bits have crossed the wire (replies,
        # whose time nothing reads, go at once)
        sent_s = max(self._state_s(), self._on_wire[-1][0] if self._on_wire else -math.inf)
        self._on_wire.append((sent_s + self.telemetry_wire_s, wp.encode("TELEMETRY", **fields)))
