"""Why a device driver failed or refused: every error the drivers raise on purpose.

Each subclasses :class:`gyrohost.errors.GyrohostError` and ``ValueError`` (bad input, refused
before anything moved) or ``RuntimeError`` (a failure while running)."""

from collections.abc import Sequence

from gyrohost.errors import GyrohostError


class ProtocolError(GyrohostError, ValueError):
    """Bytes or values that do not follow the wheel-board protocol."""


class FrameError(ProtocolError):
    """A received frame was dropped; ``kind`` names the check that failed.

    kind is one of ``bad_crc``, ``short``, ``oversize``, ``bad_cobs``, ``unknown_id``,
    ``bad_length`` (the same counters the firmware keeps).
    """

    def __init__(self, kind: str, message: str):
        super().__init__(f"{kind}: {message}")
        self.kind = kind


class WheelBoardError(GyrohostError, RuntimeError):
    """The board or the link failed (timeouts, refused commands, faults)."""


class WheelBoardTimeout(WheelBoardError, TimeoutError):
    """No reply within the time limit."""


class FirmwareMismatchError(WheelBoardError):
    """The firmware speaks another protocol version than this host."""


class DeviceError(WheelBoardError):
    """The board answered a request with an ERROR reply.

    Attributes: ``request`` (message name), ``code`` (number), ``name``, ``text``, ``detail``,
    ``latched`` (the faults the board's latest telemetry reported, named in the message when
    the refusal is FAULT_ACTIVE: the reply itself does not carry them).
    """

    def __init__(self, request: str, code: int, detail: int, latched: Sequence[str] = ()):
        from . import wheelproto as wp  # the protocol's tables; it imports this module

        self.request, self.code, self.detail = request, code, detail
        self.name, self.text = wp.error_name(code), wp.error_text(code)
        self.latched = list(latched)
        why = f"; latched: {', '.join(self.latched)}" if self.name == "FAULT_ACTIVE" else ""
        fix = wp.error_fix(code, detail)
        why += f"; run: {fix}" if fix else ""
        super().__init__(
            f"{request} refused by the wheel board: {self.name} ({self.text}), detail {detail}"
            + why
        )


class WheelFaultError(WheelBoardError):
    """Faults are latched on the board; ``faults`` lists their names."""

    def __init__(self, faults: list[str]):
        from . import wheelproto as wp

        self.faults = faults
        texts = "; ".join(f"{n}: {wp.fault_text(n)}" for n in faults)
        super().__init__(f"wheel board faults latched: {texts}")


class CalibrationError(WheelBoardError):
    """CALIBRATE_ENC failed; ``wheel``, ``reason`` (name) and ``text`` say why."""

    def __init__(self, wheel: int, detail: int):
        from . import wheelproto as wp

        self.wheel = wheel
        self.reason, self.text = wp.cal_failure(detail)
        super().__init__(f"calibration of wheel {wheel} failed: {self.reason} ({self.text})")


class ServoError(GyrohostError, RuntimeError):
    """A servo or its bus failed."""


class ServoCommError(ServoError):
    """No valid status packet (timeout, corrupt packet, port busy or failed)."""

    def __init__(self, message: str, servo_id: int, result: int) -> None:
        super().__init__(message)
        self.servo_id = servo_id
        self.result = result


class ServoTimeoutError(ServoCommError):
    """Not a byte of the status packet within the reply time-out: the servo is silent (a
    corrupt or partial packet is a plain :class:`ServoCommError`)."""


class ServoFaultError(ServoError):
    """A servo reported faults in its status error byte.

    Attributes
    ----------
    servo_id : int
    faults : tuple of str
        Names from :data:`gyrohost.drivers.mx12.FAULT_BITS`.
    states : list of ServoState
        Everything read in the same call (when raised by :meth:`StringServoBus.read_states`).
    """

    def __init__(self, message: str, servo_id: int, faults: tuple[str, ...], states=()) -> None:
        super().__init__(message)
        self.servo_id = servo_id
        self.faults = faults
        self.states = list(states)


class ServoLimitError(GyrohostError, ValueError):
    """A command outside a configured limit was refused; nothing was sent."""


class ImuError(GyrohostError, RuntimeError):
    """The IMU link failed (port error, no data in time)."""


class ImuTimeoutError(ImuError):
    """No complete sample arrived within the timeout."""


class ImuConfigError(GyrohostError, ValueError):
    """An invalid IMU driver setting (rate, mounting)."""


class PortBusyError(GyrohostError, ValueError):
    """A serial port is held by another process: refused before a byte was sent.

    Attributes: ``port``, ``pid`` and ``command`` of the holder (``""`` when it is a program
    without a gyrotens lock file that opened the device exclusively), ``lock`` (the lock file),
    ``key`` (the configuration key or device name of the port, ``""`` when not known).
    """

    def __init__(self, port: str, pid: str, command: str, lock, key: str = ""):
        self.port, self.pid, self.command, self.lock, self.key = port, pid, command, lock, key
        named = f"{port} ({key})" if key else port
        if pid:
            shown = command if len(command) <= 200 else command[:200] + "..."
            holder = f"PID {pid}" + (f" ({shown})" if command else "")
            where = f"; lock file {lock}"
        else:
            holder, where = "another program (it opened the device exclusively)", ""
        super().__init__(f"{named} is in use by {holder}{where}: wait for it to end or stop it")
