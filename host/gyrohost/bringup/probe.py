"""Which device answers on a serial port: the BWT61CL, the wheel board or a Dynamixel bus.

In this order, stopping at the first that answers:

1. WT61 frames at 115200 baud: only listened for (the IMU streams on its own; nothing is sent).
2. The wheel board's HELLO at 1 Mbaud (docs/protocol.md); its reply carries the protocol
   version. Opening a Mega's port resets it, so HELLO is repeated while its bootloader runs.
3. Dynamixel Protocol 1.0 PING of IDs 1..10 at 1 Mbps, then 57600 (the MX-12W's factory rate
   and the usual other one); a PING only asks for a status packet.

Nothing else is written: no speed, no goal, no torque; probing moves nothing.
"""

import time
from dataclasses import dataclass, field

from gyrohost.bringup import HELLO_TIMEOUT_S
from gyrohost.drivers import wheelproto as wp
from gyrohost.drivers.imu import Bwt61Parser
from gyrohost.drivers.mx12 import MODEL_MX12W

IMU_BAUD = 115200
WHEEL_BAUD = 1_000_000
SERVO_BAUDS = (1_000_000, 57600)
PING_IDS = tuple(range(1, 11))
HELLO_PERIOD_S = 0.25
"""HELLO is resent this often until a reply or the time-out (the bootloader ignores it)."""

MODEL_NAMES = {MODEL_MX12W: "MX-12W"}


@dataclass(frozen=True)
class ProbeResult:
    """What answered on one port.

    Attributes
    ----------
    port : str
    device : str
        ``"imu"``, ``"wheels"``, ``"servos"``, or ``""`` when nothing answered.
    detail : str
        One line: the IMU rate, the firmware version, the servo IDs and models.
    config_lines : tuple of str
        Lines of a rig configuration that use this port (the table header first).
    found : dict
        The raw findings (``rate_hz``; the HELLO reply's fields; ``{id: model}`` and ``baud``).
    """

    port: str
    device: str
    detail: str
    config_lines: tuple[str, ...] = ()
    found: dict = field(default_factory=dict)


def open_serial(port: str, baud: int):
    """A pyserial port opened at ``baud`` with short reads, held exclusively
    (:class:`gyrohost.drivers.portlock.LockedSerial`)."""
    from gyrohost.drivers.portlock import LockedSerial

    return LockedSerial(port, baud, timeout=0.02)


def listen_wt61(ser, window_s: float) -> float:
    """Listen to an open port for ``window_s`` s; returns the rate of whole WT61 samples, Hz
    (0.0 when none arrived)."""
    parser = Bwt61Parser()
    ser.reset_input_buffer()
    start = time.monotonic()
    times = []
    while time.monotonic() - start < window_s:
        times += [s.t_ns for s in parser.feed(ser.read(256), time.monotonic_ns())]
    if len(times) < 2:
        return float(len(times)) / window_s
    return (len(times) - 1) / ((times[-1] - times[0]) * 1e-9)


def hello(ser, timeout_s: float) -> dict | None:
    """Send HELLO on an open port until a HELLO_REPLY arrives; its fields, or None."""
    decoder = wp.FrameDecoder()
    ser.reset_input_buffer()
    deadline = time.monotonic() + timeout_s
    next_hello = 0.0
    while (now := time.monotonic()) < deadline:
        if now >= next_hello:
            ser.write(wp.encode("HELLO"))
            next_hello = now + HELLO_PERIOD_S
        for msg in decoder.feed(ser.read(256)):
            if msg.name == "HELLO_REPLY":
                return msg.fields
    return None


def ping_ids(port: str, baud: int, ids=PING_IDS, reply_timeout_s: float = 0.034) -> dict[int, int]:
    """Dynamixel Protocol 1.0 PING of ``ids`` at ``baud``, each waiting ``reply_timeout_s`` s
    beyond its transfer time: ``{id: model number}`` of those that answered (nothing else is
    written)."""
    import dynamixel_sdk as sdk

    from gyrohost.drivers.servos import PortHandler

    handler = PortHandler(port, reply_timeout_s)
    packets = sdk.PacketHandler(1.0)
    if not handler.openPort():
        raise OSError(f"cannot open {port}")
    try:
        handler.setBaudRate(baud)
        found = {}
        for servo_id in ids:
            model, result, _ = packets.ping(handler, servo_id)
            if result == sdk.COMM_SUCCESS:
                found[servo_id] = model
        return found
    finally:
        handler.closePort()


def model_name(model: int) -> str:
    """``MX-12W`` for 104, else ``model N``."""
    return MODEL_NAMES.get(model, f"model {model}")


def probe(
    port: str,
    imu_window_s: float = 0.5,
    hello_timeout_s: float = HELLO_TIMEOUT_S,
    reply_timeout_s: float = 0.034,
) -> ProbeResult:
    """Find which device answers on ``port`` (see the module's docstring for the order).

    ``imu_window_s``: WT61 frames listened for, s; ``hello_timeout_s``: HELLO repeated for, s;
    ``reply_timeout_s``: wait for each PING's status packet beyond its transfer time, s.

    Raises
    ------
    OSError
        The port cannot be opened (pyserial's ``SerialException`` is one).
    PortBusyError
        Another process holds the port (a run under way): nothing was sent.
    """
    with open_serial(port, IMU_BAUD) as ser:
        rate_hz = listen_wt61(ser, imu_window_s)
        if rate_hz > 0:
            lines = ("[imu]", f'port = "{port}"', f"baud = {IMU_BAUD}")
            return ProbeResult(
                port, "imu", f"BWT61CL, {rate_hz:.0f} Hz", lines, {"rate_hz": rate_hz}
            )
        ser.baudrate = WHEEL_BAUD  # the same open port: a second open would reset the Mega again
        fields = hello(ser, hello_timeout_s)
    if fields is not None:
        lines = ("[wheelboard]", f'port = "{port}"', f"baud = {WHEEL_BAUD}")
        return ProbeResult(port, "wheels", describe_hello(fields), lines, fields)
    for baud in SERVO_BAUDS:
        found = ping_ids(port, baud, reply_timeout_s=reply_timeout_s)
        if found:
            lines = ("[servos]", f'port = "{port}"', f"baud = {baud}")
            lines += tuple(f"# [[servos.servo]] id = {i}" for i in found)
            servos = ", ".join(f"ID {i} {model_name(m)}" for i, m in found.items())
            return ProbeResult(port, "servos", f"{servos} at {baud} baud", lines,
                               {"baud": baud, "ids": found})  # fmt: skip
    return ProbeResult(port, "", "nothing answered (WT61 at 115200, HELLO, Dynamixel PING)")


def describe_hello(fields: dict) -> str:
    """The wheel board's HELLO reply in words, with the host's protocol version if it differs."""
    text = (
        f"wheel board firmware {fields['fw_major']}.{fields['fw_minor']}, protocol "
        f"v{fields['proto_version']}, {fields['n_wheels']} wheels"
    )
    if fields["proto_version"] != wp.PROTO_VERSION:
        text += f" (this host speaks v{wp.PROTO_VERSION}: flash the firmware, 'make flash')"
    return text
