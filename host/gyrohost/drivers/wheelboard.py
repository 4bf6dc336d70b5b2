"""Client of the wheel board (four gimbal-motor speed loops on an ATmega2560) over a serial port.

Protocol: docs/protocol.md, codec: :mod:`gyrohost.drivers.wheelproto`. One reader thread decodes
every frame; telemetry goes to a bounded queue (oldest dropped) and an optional callback,
replies to the request waiting for them.

Heartbeat: the board restarts its HEARTBEAT_MS count only on the control frames HEARTBEAT,
SET_SPEEDS and STOP_ALL (docs/protocol.md), so a running wheel must be kept alive by the thread
that decides its setpoints: :meth:`set_speeds` and :meth:`heartbeat`, called from that thread at
least every HEARTBEAT_MS. A background thread beats only while every commanded speed is zero
(after connect, after STOP_ALL or a zero SET_SPEEDS: nothing on the board to stop, and no
HEARTBEAT_LOST to block the next SET_SPEEDS). If the control thread dies or stalls while a wheel
is commanded to turn, the board ramps all wheels to zero on its own, whatever other thread still
polls it.

Speeds are rad/s on this side, mrad/s on the wire.
"""

from __future__ import annotations

import contextlib
import math
import queue
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from gyrohost.drivers import wheelproto as wp

from .errors import (
    CalibrationError,
    DeviceError,
    FirmwareMismatchError,
    WheelBoardTimeout,
    WheelFaultError,
)

BAUD = 1_000_000
BOOT_WINDOW_S = 2.5
"""How long a board may stay silent after its port was opened: opening it resets the Mega into
its bootloader, which ignores the protocol for 1-2 s (docs/protocol.md#boot-state)."""
HELLO_RETRY_S = 0.25
"""The interval between two HELLOs within the boot window, s (as the bring-up probe's)."""
CONTROL_FRAMES = ("HEARTBEAT", "SET_SPEEDS", "STOP_ALL")
FRESH_S = 0.02
"""How long after a call a telemetry frame counts as made after it, s: a frame crosses a USB
serial link or a pty within a few ms, so one received 20 ms later left the board after what the
host sent before the call arrived; short beside the board's HEARTBEAT_MS window (250 ms)."""
"""The frames that restart the board's heartbeat count (the firmware's app_is_control_frame)."""


class WheelBoard:
    """Wheel-board client.

    Parameters
    ----------
    port : str or serial-like object
        Device path (opened exclusively at 1000000 baud, :mod:`gyrohost.drivers.portlock`) or
        an object with ``read``/``write``.
    heartbeat_period_s : float, s
        Period of the idle background heartbeat, and the shortest interval between two frames
        :meth:`heartbeat` sends; must be well below the board's HEARTBEAT_MS.
    on_telemetry : callable(Telemetry) or None
        Called from the reader thread for every telemetry message.
    on_fault : callable(list[str]) or None
        Called from the reader thread when fault bits newly appear in telemetry.
    telemetry_queue_len : int
        Capacity of :attr:`telemetry`; when full the oldest sample is dropped.
    boot_window_s : float, s
        How long :meth:`connect` repeats HELLO before it gives up (:data:`BOOT_WINDOW_S`).

    Attributes
    ----------
    silence_max_s : float, s
        Longest interval between two control frames to the board since the heartbeat started
        (the board latches HEARTBEAT_LOST after HEARTBEAT_MS without one).
    """

    def __init__(
        self,
        port: Any,
        heartbeat_period_s: float = 0.05,
        on_telemetry: Callable[[wp.Telemetry], None] | None = None,
        on_fault: Callable[[list[str]], None] | None = None,
        telemetry_queue_len: int = 2000,
        reply_timeout_s: float = 0.5,
        boot_window_s: float = BOOT_WINDOW_S,
    ):
        if isinstance(port, str):
            from .portlock import LockedSerial

            port = LockedSerial(port, BAUD, timeout=0.01)
        self._port = port
        self.heartbeat_period_s = heartbeat_period_s
        self.reply_timeout_s = reply_timeout_s
        self.boot_window_s = boot_window_s
        self.on_telemetry = on_telemetry
        self.on_fault = on_fault
        self.telemetry: queue.Queue[wp.Telemetry] = queue.Queue(telemetry_queue_len)
        self.decoder = wp.FrameDecoder()
        self.faults: list[str] = []
        self.last_telemetry: wp.Telemetry | None = None
        self.telemetry_dropped = 0
        self.hello: dict[str, int] | None = None
        self.silence_max_s = 0.0  # longest time without a control frame, heartbeat on
        self._last_sent_s: float | None = None  # the last control frame
        self._driving = False  # a nonzero speed commanded: only the caller's frames keep it
        self._replies: queue.Queue[wp.Message] = queue.Queue()
        self._write_lock = threading.Lock()
        self._request_lock = threading.Lock()
        self._stop = threading.Event()
        self._heartbeat_on = threading.Event()
        self._reader = threading.Thread(target=self._read_loop, name="wheelboard-rx", daemon=True)
        self._beater = threading.Thread(target=self._beat_loop, name="wheelboard-hb", daemon=True)
        self._reader.start()
        self._beater.start()

    # ------------------------------------------------------------ life cycle
    def connect(self) -> dict[str, int]:
        """Handshake: HELLO (repeated through the boot window: a board whose port was just
        opened runs its bootloader first), refuse another protocol version, start the
        heartbeat."""
        deadline = time.monotonic() + self.boot_window_s
        while True:
            try:
                reply = self._request(
                    "HELLO", {}, ("HELLO_REPLY",), min(HELLO_RETRY_S, self.reply_timeout_s)
                )
                break
            except WheelBoardTimeout:
                if time.monotonic() >= deadline:
                    raise WheelBoardTimeout(
                        f"no HELLO_REPLY reply to HELLO within {self.boot_window_s:g} s of "
                        "HELLOs (a board whose port opens runs its bootloader for 1-2 s first; "
                        f"is the board connected and running protocol v{wp.PROTO_VERSION}?)"
                    ) from None
        fields = reply.fields
        if fields["proto_version"] != wp.PROTO_VERSION:
            raise FirmwareMismatchError(
                f"wheel board firmware {fields['fw_major']}.{fields['fw_minor']} speaks protocol "
                f"v{fields['proto_version']}, this host speaks v{wp.PROTO_VERSION}: flash the "
                "matching firmware (pio run -e megaatmega2560 -t upload) or update gyrohost"
            )
        if fields["n_params"] != len(wp.PARAMS) or fields["n_wheels"] != wp.N_WHEELS:
            raise FirmwareMismatchError(
                f"wheel board reports {fields['n_wheels']} wheels and {fields['n_params']} "
                f"parameters, this host expects {wp.N_WHEELS} and {len(wp.PARAMS)}"
            )
        self.hello = fields
        # HELLO is a query: the board's heartbeat count runs on until this first control frame
        self._send("HEARTBEAT", {})
        self._heartbeat_on.set()
        return fields

    def close(self) -> None:
        """Stop all wheels (best effort), stop the threads and close the port."""
        try:
            if self.hello is not None:
                self._send("STOP_ALL", {})
        except OSError:
            pass
        self._heartbeat_on.clear()
        self._stop.set()
        self._beater.join(1.0)
        self._reader.join(1.0)
        close = getattr(self._port, "close", None)
        if close is not None:
            close()

    def __enter__(self) -> WheelBoard:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------ commands
    def set_speeds(self, omega_rad_s: Sequence[float], confirm: bool = True) -> None:
        """Command the four wheel speeds, rad/s.

        The board replies only on refusal; with ``confirm`` a GET_STATS round trip after the
        setpoints proves they were accepted (replies come in order), else a refusal surfaces
        as DeviceError on a later request.
        """
        if len(omega_rad_s) != wp.N_WHEELS:
            raise ValueError(f"set_speeds: need {wp.N_WHEELS} speeds, got {len(omega_rad_s)}")
        fields = {}
        for i, w in enumerate(omega_rad_s):
            if not math.isfinite(w):
                raise ValueError(f"set_speeds: wheel {i} speed {w} is not finite")
            mrad = round(w * 1000.0)
            if abs(mrad) > 2**31 - 1:
                raise ValueError(f"set_speeds: wheel {i} speed {w} rad/s out of the int32 range")
            fields[f"w{i}_mrad_s"] = mrad
        previous, self._driving = self._driving, any(fields.values())
        if not confirm:
            self._send("SET_SPEEDS", fields)
            return
        with self._request_lock:
            self._drain_replies()
            self._send("SET_SPEEDS", fields)
            self._send("GET_STATS", {})
            try:
                self._await(("STATS",), ("SET_SPEEDS", "GET_STATS"))
            except DeviceError:  # refused: the board holds what it held before
                self._driving = previous
                # the STATS comes after the refusal: taken here, or the next request could
                # take it for its own reply and pass a refusal of its own on to the one after
                with contextlib.suppress(WheelBoardTimeout):
                    self._await(("STATS",), ("GET_STATS",))
                raise

    def stop_all(self) -> None:
        """Ramp all wheels to zero at DECEL_RAD_S2."""
        self._driving = False
        self._request("STOP_ALL", {}, ("ACK",))

    def heartbeat(self) -> None:
        """Tell the board the caller's control thread is alive: a HEARTBEAT, unless a control
        frame went out within ``heartbeat_period_s``. Call it from the thread that decides the
        setpoints, every control tick."""
        last = self._last_sent_s
        if last is None or time.monotonic() - last >= self.heartbeat_period_s:
            self._send("HEARTBEAT", {})

    def clear_faults(self, names: Sequence[str]) -> list[str]:
        """Clear the latched faults ``names``, and only those; returns them.

        The caller names each fault it clears, after it has reported them to the user (a fault
        that latched since stays latched and shows in the next telemetry). An empty list sends
        nothing.
        """
        names = list(dict.fromkeys(names))
        if not names:
            return []
        self._request("CLEAR_FAULTS", {"mask": wp.fault_mask(names)}, ("ACK",))
        self.faults = [n for n in self.faults if n not in names]
        return names

    def latched_faults(self, timeout_s: float | None = None) -> list[str]:
        """The faults of the first telemetry frame received :data:`FRESH_S` or more after this
        call: one the board made after the frames sent before the call reached it (a board
        that latched HEARTBEAT_LOST just before the connect's first HEARTBEAT shows it there,
        where a frame still on the link would not)."""
        timeout_s = timeout_s or self.reply_timeout_s
        now = time.monotonic()
        fresh, deadline = now + FRESH_S, now + timeout_s
        while True:
            try:
                frame = self.telemetry.get(timeout=max(deadline - time.monotonic(), 0.0))
            except queue.Empty:
                raise WheelBoardTimeout(
                    f"no wheel-board telemetry within {timeout_s:.3f} s (TELEMETRY_DIV 0?)"
                ) from None
            if time.monotonic() >= fresh:
                return frame.fault_names

    def calibrate(self, wheel: int, save: bool = True, timeout_s: float = 5.0) -> int:
        """Find wheel ``wheel``'s electrical zero with its motor (CALIBRATE_ENC, about 1.8 s with
        the wheel turning back and forth by one electrical turn); returns the new ENC_OFFSET.

        With ``save`` the parameters are written to EEPROM afterwards. Raises
        :class:`CalibrationError` naming the reason when the board finds the rotor did not
        move, moved the wrong amount or the wrong way.
        """
        if not 0 <= wheel < wp.N_WHEELS:
            raise ValueError(f"calibrate: wheel {wheel} is not one of 0..{wp.N_WHEELS - 1}")
        try:
            self._request("CALIBRATE_ENC", {"wheel": wheel}, ("ACK",), timeout_s=timeout_s)
        except DeviceError as exc:
            if exc.name != "CALIBRATION_FAILED":
                raise
            raise CalibrationError(wheel, exc.detail) from None
        offset = self.get_param(f"ENC_OFFSET_M{wheel}")
        if save:
            self.save_params()
        return offset

    def get_param(self, name: str) -> int:
        spec = self._param(name)
        return self._request("PARAM_GET", {"param_id": spec.id}, ("PARAM_VALUE",)).fields["value"]

    def set_param(self, name: str, value: int) -> int:
        """Set a parameter (RAM); returns the value the board now holds. See save_params()."""
        spec = self._param(name)
        if not spec.min <= int(value) <= spec.max:
            raise ValueError(
                f"parameter {name}: {value} outside [{spec.min}, {spec.max}] {spec.unit}"
            )
        reply = self._request(
            "PARAM_SET", {"param_id": spec.id, "value": int(value)}, ("PARAM_VALUE",)
        )
        return reply.fields["value"]

    def save_params(self, timeout_s: float = 2.0) -> None:
        """Write all parameters to EEPROM; returns when the board has written the last byte."""
        self._request("PARAM_SAVE", {}, ("ACK",), timeout_s=timeout_s)

    def load_defaults(self) -> None:
        self._request("PARAM_DEFAULTS", {}, ("ACK",))

    def stats(self) -> dict[str, int]:
        return self._request("GET_STATS", {}, ("STATS",)).fields

    def check_faults(self) -> None:
        """Raise WheelFaultError if the last telemetry showed latched faults."""
        if self.faults:
            raise WheelFaultError(list(self.faults))

    # ------------------------------------------------------------ internals
    @staticmethod
    def _param(name: str) -> wp.ParamSpec:
        spec = wp.PARAM_BY_NAME.get(name)
        if spec is None:
            raise ValueError(
                f"unknown wheel-board parameter {name!r}; known: {sorted(wp.PARAM_BY_NAME)}"
            )
        return spec

    def _send(self, name: str, fields: dict[str, int]) -> None:
        """Write one frame. A control frame restarts the board's HEARTBEAT_MS count: the longest
        gap between two, once the heartbeat runs, says how near a stalled host came to the
        board's fail-safe."""
        data = wp.encode(name, **fields)
        with self._write_lock:
            self._port.write(data)
            if name not in CONTROL_FRAMES:
                return
            now_s = time.monotonic()
            if self._heartbeat_on.is_set() and self._last_sent_s is not None:
                self.silence_max_s = max(self.silence_max_s, now_s - self._last_sent_s)
            self._last_sent_s = now_s

    def _drain_replies(self) -> None:
        while True:
            try:
                self._replies.get_nowait()
            except queue.Empty:
                return

    def _request(
        self,
        name: str,
        fields: dict[str, int],
        expect: tuple[str, ...],
        timeout_s: float | None = None,
    ) -> wp.Message:
        with self._request_lock:
            self._drain_replies()
            self._send(name, fields)
            return self._await(expect, (name,), timeout_s)

    def _await(
        self, expect: tuple[str, ...], requests: tuple[str, ...], timeout_s: float | None = None
    ) -> wp.Message:
        deadline = time.monotonic() + (timeout_s or self.reply_timeout_s)
        req_ids = {wp.BY_NAME[r].id for r in requests}
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise WheelBoardTimeout(
                    f"no {'/'.join(expect)} reply to {'+'.join(requests)} within "
                    f"{timeout_s or self.reply_timeout_s:.3f} s (is the board connected and "
                    f"running protocol v{wp.PROTO_VERSION}?)"
                )
            try:
                msg = self._replies.get(timeout=left)
            except queue.Empty:
                continue
            if msg.name == "ERROR" and msg.fields["req_id"] in req_ids:
                req = wp.BY_ID[msg.fields["req_id"]].name
                raise DeviceError(req, msg.fields["code"], msg.fields["detail"], self.faults)
            if msg.name == "ACK" and msg.fields["req_id"] not in req_ids:
                continue
            if msg.name in expect:
                return msg

    def _read_loop(self) -> None:
        while not self._stop.is_set():
            try:
                # what has come, as soon as a byte has: a frame's arrival stamp is when it
                # came, not when a fixed count filled or the read timed out
                data = self._port.read(max(self._port.in_waiting, 1))
            except (OSError, ValueError, TypeError):
                if self._stop.is_set():
                    return
                time.sleep(0.01)
                continue
            if not data:
                continue
            for msg in self.decoder.feed(data):
                self._route(msg)

    def _route(self, msg: wp.Message) -> None:
        if msg.name != "TELEMETRY":
            self._replies.put(msg)
            return
        tel = wp.Telemetry.from_message(msg)
        self.last_telemetry = tel
        if self.telemetry.full():
            try:
                self.telemetry.get_nowait()
                self.telemetry_dropped += 1
            except queue.Empty:
                pass
        self.telemetry.put_nowait(tel)
        names = tel.fault_names
        new = [n for n in names if n not in self.faults]
        self.faults = names
        if self.on_telemetry is not None:
            self.on_telemetry(tel)
        if new and self.on_fault is not None:
            self.on_fault(new)

    def _beat_loop(self) -> None:
        while not self._stop.wait(self.heartbeat_period_s):
            if self._heartbeat_on.is_set() and not self._driving:
                try:
                    self._send("HEARTBEAT", {})
                except OSError:
                    pass
