"""String servos moved on the user's command on the first day: one string lengthened or
shortened by a given amount (``gyrotens servos jog``), every string driven to the scene's start
length (``gyrotens servos home``), as a run's start check wants them (docs/bring-up.md).

Each move stays within the servo's ``[min_length_m, max_length_m]`` (a goal outside is refused
before anything moves), at its ``max_speed_m_s``, with the torque limited to the
configuration's ``[run] max_servo_load``; afterwards the servos hold where they arrived.
"""

import time
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import replace

from gyrohost.config import RigConfig
from gyrohost.drivers import mx12
from gyrohost.drivers.errors import ServoLimitError
from gyrohost.drivers.servos import StringServoBus

from .devices import Target
from .errors import ServoSetupError, SetupInputError
from .placeholders import find_placeholders

ARRIVED_STEPS = 2
"""A servo this close to its goal has arrived, steps (0.18 degrees)."""
POLL_S = 0.02
SETTLE_MARGIN = 2.0
"""A move may take this many times its distance over ``max_speed_m_s``, plus :data:`SETTLE_S`."""
SETTLE_S = 3.0
"""Time a move may take beyond its travel, s: the servo's acceleration and the bus's replies on a
loaded host; a blocked servo is still found within seconds."""

Report = Callable[[str], None]


def servo_named(config: RigConfig, name: str):
    """The ``[[servos.servo]]`` named ``name``.

    Raises
    ------
    SetupInputError
        No servo has that name (the message lists those configured).
    """
    for servo in config.servos.servo:
        if servo.name == name:
            return servo
    known = ", ".join(s.name for s in config.servos.servo) or "none"
    raise SetupInputError(f"{config.source}: no servo named {name!r} (configured: {known})")


def servos_config(target: Target) -> RigConfig:
    """The configuration of ``target`` with the servo bus's port, refused while a servo's zero is
    a placeholder: its lengths, and so its limits, would be wrong.

    Raises
    ------
    SetupInputError
        The port cannot be opened, or a ``zero_position``/``length_at_zero_m`` is still the
        template's (the message names them and the command that calibrates them).
    """
    config = target.rig("servos")
    if config.source.endswith(".toml"):
        unset = [p.key for p in find_placeholders(config.source) if p.required]
        if unset:
            raise SetupInputError(
                f"{config.source}: the servos' lengths are not calibrated ({', '.join(unset)}): "
                "'gyrotens servos zero' first (docs/bring-up.md, step 8)"
            )
    return config


def start_lengths(config: RigConfig) -> dict[str, float]:
    """Servo name -> the scene's initial rest length of the string it winds, m (servos that
    wind no scene string are left out)."""
    from gyrotensegrity import load_scene

    rest = {s.name: s.rest_length(0.0) for s in load_scene(config.scene_path).strings}
    return {s.name: rest[s.string] for s in config.servos.servo if s.string in rest}


def jog(target: Target, name: str, by_m: float, report: Report) -> float:
    """Lengthen (``by_m`` > 0) or shorten the string of servo ``name`` by ``by_m`` (the servo bus
    of ``target``); returns its length after the move, m.

    Raises
    ------
    SetupInputError
        No such servo, or the goal is outside its length limits (nothing moved).
    ServoSetupError
        The servo did not arrive in time.
    """
    config = servos_config(target)
    servo = servo_named(config, name)
    bus_config = replace(config.servos, servo=(servo,))
    with _limited_bus(bus_config, config.run.max_servo_load) as bus:
        return move(bus, {name: bus.read_lengths()[name] + by_m}, report)[name]


def home(target: Target, report: Report) -> dict[str, float]:
    """Drive every servo's string (the servo bus of ``target``) to the scene's start length;
    returns the lengths reached, m.

    Raises
    ------
    SetupInputError
        No servo winds a scene string, or a start length is outside a servo's limits.
    """
    config = servos_config(target)
    goals = start_lengths(config)
    if not goals:
        raise SetupInputError(f"{config.source}: no servo winds a string of the scene")
    with _limited_bus(config.servos, config.run.max_servo_load) as bus:
        return move(bus, goals, report)


def move(bus: StringServoBus, goals_m: dict[str, float], report: Report) -> dict[str, float]:
    """Command ``goals_m`` (name -> m) at each servo's ``max_speed_m_s`` and wait until every
    servo is there; returns the lengths read then, m.

    Raises
    ------
    SetupInputError
        A goal is outside its servo's limits: nothing was sent.
    ServoSetupError
        A servo did not arrive within :data:`SETTLE_MARGIN` times its travel time.
    """
    before = bus.read_lengths()
    try:
        steps = bus.command_lengths(goals_m)
    except ServoLimitError as exc:
        raise SetupInputError(str(exc)) from None
    for name, goal in goals_m.items():
        report(f"servo '{name}': {before[name]:.4f} m -> {goal:.4f} m")
    travel_s = max(abs(goals_m[n] - before[n]) / bus.servos[n].max_speed_m_s for n in goals_m)
    deadline = time.monotonic() + SETTLE_MARGIN * travel_s + SETTLE_S
    while True:
        states = {s.name: s for s in bus.read_states()}
        if all(abs(states[n].position_steps - steps[n]) <= ARRIVED_STEPS for n in steps):
            break
        if time.monotonic() > deadline:
            late = [n for n in steps if abs(states[n].position_steps - steps[n]) > ARRIVED_STEPS]
            raise ServoSetupError(f"servos {late} did not reach their goals in time (blocked?)")
        time.sleep(POLL_S)
    lengths = {n: states[n].length_m for n in goals_m}
    for name, length in lengths.items():
        report(f"servo '{name}': at {length:.4f} m, holding")
    return lengths


@contextmanager
def _limited_bus(bus_config, max_load: float):
    """The bus opened, its servos in multi-turn mode and holding, the torque limited to
    ``max_load`` (fraction) until the block ends; they go on holding after it."""
    with StringServoBus(bus_config) as bus:
        bus.configure()
        limits = {s.id: torque_limit(bus, s.id, round(max_load * 1023)) for s in bus_config.servo}
        try:
            yield bus
        finally:
            bus.hold()
            for servo_id, value in limits.items():
                torque_limit(bus, servo_id, value)


def torque_limit(bus: StringServoBus, servo_id: int, value: int) -> int:
    """Write a servo's torque limit (RAM, reset at power-up); returns the one it replaced."""
    packets, port = bus.packets, bus.port
    before, result, _ = packets.read2ByteTxRx(port, servo_id, mx12.Addr.TORQUE_LIMIT)
    if result != 0:
        raise ServoSetupError(f"servo ID {servo_id}: torque limit not read ({result})")
    packets.write2ByteTxRx(port, servo_id, mx12.Addr.TORQUE_LIMIT, value)
    return before
