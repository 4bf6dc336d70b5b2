"""Setting up an MX-12W string servo: its ID and baud rate (both ship as ID 1 at 1 Mbps), and the
zero of its length model (docs/bring-up.md).

The ID is changed only when exactly one servo answers on the bus (two servos on one ID would
both take the new one), and the change is confirmed by a PING at the new ID and baud rate. The
calibration moves the servo only after the caller's confirmation, with the torque limited to the
configuration's ``[run] max_servo_load`` and the speed to the servo's ``max_speed_m_s``.
"""

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

from gyrohost.bringup.probe import model_name, ping_ids
from gyrohost.config import ServoBusConfig, ServoConfig
from gyrohost.drivers import mx12
from gyrohost.drivers.servos import PortHandler, StringServoBus

from .errors import ServoSetupError
from .servo_moves import torque_limit

BAUD_REGISTER = {2_000_000: 0, 1_000_000: 1, 500_000: 3, 115200: 16, 57600: 34}
"""Bus baud rate -> MX-12W baud register (2 Mbps / (value + 1); 57600 is 57142, within 1 %)."""
ALL_IDS = range(0, 253)
SETTLE_S = 0.05
"""Wait after an EEPROM write before the servo is asked again, s."""


@dataclass(frozen=True)
class IdChange:
    """A servo's ID and baud rate before and after :func:`change_id`; ``model`` its number."""

    old_id: int
    new_id: int
    old_baud: int
    new_baud: int
    model: int

    def describe(self) -> str:
        return (
            f"{model_name(self.model)}: ID {self.old_id} at {self.old_baud} baud -> ID "
            f"{self.new_id} at {self.new_baud} baud (confirmed by PING)"
        )


def change_id(
    port: str,
    baud: int,
    new_id: int,
    new_baud: int | None = None,
    ids=ALL_IDS,
    reply_timeout_s: float = 0.034,
) -> IdChange:
    """Give the lone servo on ``port`` the ID ``new_id`` (and the baud rate ``new_baud``).

    Raises
    ------
    ServoSetupError
        No servo or more than one answered among ``ids`` at ``baud``; or the servo does not
        answer at its new ID and baud rate.
    """
    new_baud = baud if new_baud is None else new_baud
    if new_baud not in BAUD_REGISTER or not 0 <= new_id <= 252:
        raise ServoSetupError(
            f"new ID {new_id} must be 0..252 and new baud {new_baud} one of {sorted(BAUD_REGISTER)}"
        )
    found = ping_ids(port, baud, ids, reply_timeout_s)
    if len(found) != 1:
        what = f"IDs {sorted(found)} answered" if found else "no servo answered"
        raise ServoSetupError(
            f"{port} at {baud} baud: {what} (IDs {min(ids)}..{max(ids)}): connect exactly one "
            "servo to the bus to change its ID"
        )
    ((old_id, model),) = found.items()
    _write_without_reply(port, baud, old_id, mx12.Addr.ID, new_id, reply_timeout_s)
    if new_baud != baud:
        _write_without_reply(port, baud, new_id, mx12.Addr.BAUD, BAUD_REGISTER[new_baud],
                             reply_timeout_s)  # fmt: skip
    confirmed = ping_ids(port, new_baud, [new_id], reply_timeout_s)
    if confirmed.get(new_id) != model:
        raise ServoSetupError(
            f"{port}: no reply from ID {new_id} at {new_baud} baud after the change (power the "
            "servo off and on, then 'gyrotens ports')"
        )
    return IdChange(old_id, new_id, baud, new_baud, model)


def _write_without_reply(port, baud, servo_id, addr, value, reply_timeout_s) -> None:
    """WRITE one byte without waiting for the status packet: after an ID or baud change the
    servo answers as the new one, which the SDK would not take for the reply."""
    import dynamixel_sdk as sdk

    handler = PortHandler(port, reply_timeout_s)
    if not handler.openPort():
        raise ServoSetupError(f"cannot open {port}")
    try:
        handler.setBaudRate(baud)
        sdk.PacketHandler(1.0).write1ByteTxOnly(handler, servo_id, addr, value)
        time.sleep(SETTLE_S)
    finally:
        handler.closePort()


def read_zero(
    bus_config: ServoBusConfig, servo: ServoConfig, measured: Callable[[], float]
) -> tuple[int, float]:
    """Switch the servo's torque off, let the string be wound by hand (``measured`` returns once
    it is, with the length measured between its nodes, m) and return the present position,
    steps, and that length: the ``zero_position`` and its ``length_at_zero_m``."""
    with StringServoBus(replace(bus_config, servo=(servo,))) as bus:
        bus.ping_all()
        bus.set_torque(False)
        length_m = measured()
        return bus.read_states()[0].position_steps, length_m


def check_sign(
    bus_config: ServoBusConfig,
    servo: ServoConfig,
    step_m: float,
    max_load: float,
    confirm: Callable[[str], bool],
    timeout_s: float = 10.0,
) -> tuple[float, int]:
    """Move the calibrated ``servo`` ``step_m`` longer (shorter when that passes its
    ``max_length_m``) and back, once ``confirm`` agrees.

    The torque limit is ``max_load`` (fraction of the maximum torque) during the move and
    restored after; the torque is off at the end. Returns the length commanded, m, and the
    position change of the move, steps: whether the string did lengthen tells ``length_sign``.

    Raises
    ------
    ServoSetupError
        ``confirm`` said no (nothing moved), or the servo did not reach its goal in time.
    """
    length0 = servo.length_at_zero_m
    goal = length0 + step_m if length0 + step_m <= servo.max_length_m else length0 - step_m
    question = (
        f"move servo '{servo.name}' (ID {servo.id}) from {length0:.4f} m to {goal:.4f} m and "
        f"back, at most {servo.max_speed_m_s:g} m/s, torque limit {100 * max_load:.0f} %?"
    )
    if not confirm(question):
        raise ServoSetupError("not confirmed: nothing moved")
    with StringServoBus(replace(bus_config, servo=(servo,))) as bus:
        limit_before = torque_limit(bus, servo.id, round(max_load * 1023))
        try:
            bus.configure()  # multi-turn mode, torque on, holding where it is
            start = bus.read_states()[0].position_steps
            moved = _move(bus, servo, goal, timeout_s) - start
            _move(bus, servo, length0, timeout_s)
        finally:
            bus.set_torque(False)
            torque_limit(bus, servo.id, limit_before)
    return goal, moved


def _move(bus: StringServoBus, servo: ServoConfig, length_m: float, timeout_s: float) -> int:
    """Command ``length_m`` and wait until the servo is there; returns its position, steps."""
    goal = bus.command_lengths({servo.name: length_m})[servo.name]
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        position = bus.read_states()[0].position_steps
        if abs(position - goal) <= 2:
            return position
        time.sleep(0.02)
    raise ServoSetupError(
        f"servo '{servo.name}' did not reach {length_m:.4f} m in {timeout_s:g} s (goal {goal} "
        f"steps, at {position})"
    )
