"""The Dynamixel MX-12W in Protocol 1.0: control table, status error bits and unit conversions.

Shared by the driver (:mod:`gyrohost.drivers.servos`) and the emulator
(:mod:`gyrohost.simrig.servo_emu`), so both read the same table; imports no SDK. The SDK returns raw
unsigned words: positions are 16-bit two's complement, present speed and load are
sign-magnitude (bit 10 = clockwise = negative here). A string wound on a pulley of radius ``r``
in multi-turn mode (4096 steps per turn) has length
``L = length_at_zero_m + length_sign * (p - zero_position) * 2 pi r / 4096``.
"""

import math

from gyrohost.config import ServoConfig

MODEL_MX12W = 104
STEPS_PER_TURN = 4096
SPEED_UNIT_RAD_S = 0.916 * 2.0 * math.pi / 60.0
"""Moving/present speed per unit, rad/s (0.916 rpm)."""
LOAD_UNIT = 0.001
"""Present load per unit, fraction of the maximum torque (0.1 %)."""
MULTI_TURN_LIMIT = 4095
SPEED_MAX_UNITS = 1023


class Addr:
    """MX-12W control table addresses (Protocol 1.0)."""

    MODEL = 0
    ID = 3
    BAUD = 4
    RETURN_DELAY = 5
    CW_LIMIT = 6
    CCW_LIMIT = 8
    STATUS_RETURN = 16
    SHUTDOWN = 18
    MULTI_TURN_OFFSET = 20
    RESOLUTION_DIVIDER = 22
    TORQUE_ENABLE = 24
    GOAL_POSITION = 30
    MOVING_SPEED = 32
    TORQUE_LIMIT = 34
    PRESENT_POSITION = 36
    PRESENT_SPEED = 38
    PRESENT_LOAD = 40
    MOVING = 46
    GOAL_ACCELERATION = 73


FAULT_BITS = {
    0x01: "input voltage",
    0x02: "angle limit",
    0x04: "overheating",
    0x08: "range",
    0x10: "checksum",
    0x20: "overload",
    0x40: "instruction",
}
"""Status packet error bits and their names."""


def fault_names(error: int) -> tuple[str, ...]:
    """Names of the fault bits set in a status ``error`` byte."""
    return tuple(name for bit, name in FAULT_BITS.items() if error & bit)


def int16_from_word(word: int) -> int:
    """Signed value of a 16-bit two's complement ``word``."""
    word &= 0xFFFF
    return word - 0x10000 if word & 0x8000 else word


def word_from_int16(value: int) -> int:
    """16-bit two's complement word of a signed ``value`` in -32768..32767."""
    if not -0x8000 <= value <= 0x7FFF:
        raise ValueError(f"{value} does not fit a signed 16-bit word")
    return value & 0xFFFF


def signed_from_sign_magnitude(word: int) -> int:
    """Signed value of an MX sign-magnitude word (bits 0-9 magnitude, bit 10 = negative)."""
    magnitude = word & 0x3FF
    return -magnitude if word & 0x400 else magnitude


def sign_magnitude_from_signed(value: int) -> int:
    """MX sign-magnitude word of a signed ``value`` in -1023..1023."""
    if abs(value) > 0x3FF:
        raise ValueError(f"{value} does not fit a 10-bit magnitude")
    return (abs(value) & 0x3FF) | (0x400 if value < 0 else 0)


def steps_per_metre(servo: ServoConfig) -> float:
    """Position steps per metre of string."""
    return STEPS_PER_TURN / (2.0 * math.pi * servo.pulley_radius_m)


def length_to_steps(servo: ServoConfig, length_m: float) -> float:
    """Servo position, steps (not rounded), at which the string is ``length_m`` m long."""
    delta_m = length_m - servo.length_at_zero_m
    return servo.zero_position + servo.length_sign * delta_m * steps_per_metre(servo)


def steps_to_length(servo: ServoConfig, position_steps: float) -> float:
    """String length, m, at servo position ``position_steps``."""
    delta_steps = position_steps - servo.zero_position
    return servo.length_at_zero_m + servo.length_sign * delta_steps / steps_per_metre(servo)


def string_speed_per_unit(servo: ServoConfig) -> float:
    """String speed, m/s, of one moving-speed unit."""
    return SPEED_UNIT_RAD_S * servo.pulley_radius_m
