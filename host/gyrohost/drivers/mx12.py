"""The Dynamixel MX-12W in Protocol 1.0: control table, status error bits and unit conversions.

Shared by the driver (:mod:`gyrohost.drivers.servos`) and the emulator
(:mod:`gyrohost.simrig.servo_emu`), so both read the same table; imports no SDK. The SDK returns raw
unsigned words: positions are 16-bit two's complement, present speed and load are
sign-magnitude (bit 10 = clockwise = negative here). A string wound on a pulley of radius ``r``
in multi-turn mode (4096 steps per turn) has length
``L = length_at_zero_m + length_sign * (p - zero_position) * 2 pi r / 4096``.
"""

import math

import numpy as np

from gyrohost.config import ServoConfig

MODEL_MX12W = 104
STEPS_PER_TURN = 4096
SPEED_UNIT_RAD_S = 0.916 * 2.0 * math.pi / 60.0
"""Moving/present speed per unit, rad/s (0.916 rpm)."""
LOAD_UNIT = 0.001
"""Present load per unit, fraction of the maximum torque (0.1 %)."""
MULTI_TURN_LIMIT = 4095
SPEED_MAX_UNITS = 1023
P_GAIN_FACTORY = 8
"""The MX-12W's P gain (address 28) as shipped (its D gain 8, I gain 0)."""


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
    P_GAIN = 28
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


def position_lag_s(p_gain: int, no_load_speed_rpm: float) -> float:
    """The time constant of an MX's position loop below its speed limit, s.

    The manual equates a P gain with the older servos' compliance slope (P 8, 32, 128 for
    slopes of 128, 32, 8 AX steps of 300/1024 deg): the output rises in proportion to the
    error over a band of ``300 / P`` degrees and is full beyond it, and full output turns the
    shaft at its no-load speed. The shaft then closes an error ``e`` inside the band at
    ``no_load * e / band``: a first-order lag of ``band / no_load`` = ``50 / (P * rpm)`` s
    (13.3 ms at the factory P 8 and 470 rpm). Friction and load slow it; a step response on
    the rig measures it (``gyrotens identify`` fits it from the servos' reads). A P gain of
    0 gives no output: an infinite lag.
    """
    if p_gain <= 0:
        return math.inf
    return 50.0 / (p_gain * no_load_speed_rpm)


def lag_error_after(error, dt_s: float, lag_s: float, max_speed) -> np.ndarray:
    """A position loop's error after ``dt_s`` s from ``error``: closing at ``max_speed`` (same
    units per s) while its output asks for more, as a first-order lag ``lag_s`` within
    (:func:`position_lag_s`), exactly. Element-wise over arrays; an infinite speed limit
    leaves the lag alone.

    The error closes at the limit until it is down to ``max_speed lag_s``, taking
    ``t1 = (|e| - max_speed lag_s) / max_speed``; it then decays as ``exp(-(dt - t1) / lag)``.
    """
    error = np.asarray(error, dtype=float)
    size, knee = np.abs(error), np.asarray(max_speed, dtype=float) * lag_s
    over = size > knee
    if not over.any():  # the lag alone (the filter asks every step: the short way)
        return error * np.exp(-np.maximum(dt_s, 0.0) / lag_s)
    with np.errstate(invalid="ignore", divide="ignore"):  # inf * 0 in the branch not taken
        t_knee = np.where(over, (size - knee) / max_speed, 0.0)
        linear = np.where(over, np.maximum(size - max_speed * dt_s, knee), size)
    decayed = np.minimum(size, knee) * np.exp(-np.maximum(dt_s - t_knee, 0.0) / lag_s)
    return np.sign(error) * np.where(dt_s <= t_knee, linear, decayed)


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
