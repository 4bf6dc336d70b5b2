"""The EKF's settings for the simulated rig, derived from its emulators and its truth.

A run on the simulated rig takes its ``[estimator]`` table like any rig (the shipped
``sim-rig`` configuration writes these values out; a test keeps them equal); the in-process
SIL and the studies start from :func:`emulator_keys` itself, so that a changed emulator
setting reaches their filter.
"""

import math

from gyrohost.config import RigConfig
from gyrohost.drivers import wheelproto as wp
from gyrohost.drivers.mx12 import P_GAIN_FACTORY, position_lag_s, steps_per_metre
from gyrohost.estimator.config import (
    MIN_WHEEL_WALK,
    SPEED_FILTER_DELAY_S,
    imu_wire_counts,
    rig_keys,
    servo_hold_std,
)
from gyrohost.simrig.config import sim_config
from gyrohost.simrig.imu_emu import wire_time_s

SERVO_BUS_SPAN_S = 1.0e-3
"""The span over which a goal or a read request reaches an emulated servo after the host's
stamp, s, taken uniform: the millisecond a real rig's USB frame bounds it by. The emulated bus
takes the bytes as they arrive, a few tenths of a millisecond after the stamp (docs/rig.md)."""


IMU_WAKE_UP_STD_S = 2.0e-4
"""How far the host's IMU grid lies behind the samples beyond the wire, s, taken as a run's
constant of this 1-sigma: the pty's shortest delivery and the rig's and the reader's wake-up,
0.11-0.20 ms on the three runs measured (docs/estimator-noise.md#the-imus-latency), a few
tenths of a millisecond on a loaded machine."""


def emulated_servo_lag_s(rig: RigConfig) -> float:
    """The emulated MX-12W's position-loop lag, s: its factory P gain at the ``[sim.servos]``
    no-load speed (:func:`~gyrohost.drivers.mx12.position_lag_s`)."""
    return position_lag_s(P_GAIN_FACTORY, sim_config(rig).servos.no_load_speed_rpm)


def emulator_keys(rig: RigConfig) -> dict:
    """The EKF's keys describing the simulated rig of ``rig`` (its ``[sim]`` tables): the noise
    of its emulated devices, the attachment of its IMU, the steps of its truth, with the
    :func:`~gyrohost.estimator.config.rig_keys` of its ``[imu]`` and ``[servos]`` tables.

    White noise std = density * sqrt(rate / 2), combined with the quantisation of the wire
    format (one count / sqrt(12)); the IMU's biases are states with their spreads as priors.
    Returns a dict for :func:`config_from_dict`.
    """
    rate_count, accel_count, angle_count = imu_wire_counts()
    root = math.sqrt(rig.imu.rate_hz / 2.0)
    sim = sim_config(rig)
    emu = sim.imu

    def std(white, count, bias=0.0):
        return math.sqrt(white**2 + count**2 / 12.0 + bias**2)

    accel_white = emu.accel_noise_density_m_s2_rthz * root
    wheels = sim.wheels
    count_m = max((1.0 / steps_per_metre(s) for s in rig.servos.servo), default=0.0)
    lag_s = emulated_servo_lag_s(rig)
    time_std_s = SERVO_BUS_SPAN_S / math.sqrt(12.0)
    return {
        # a sample is whole for the host when its last byte has crossed the wire, that long
        # after it was taken (plus the truth's own latency, a drawn sensor's); the rig's loop
        # wakes for it then, and the grid the host rebuilds keeps the earliest arrivals: it
        # lies behind the samples by the wire and the loop's and the reader's shortest
        # wake-up, the same for the whole run (0.11-0.20 ms measured, the machine's): a
        # considered latency error of IMU_WAKE_UP_STD_S, no spread
        # (docs/estimator-noise.md#the-imus-latency; gyrotens identify fits the whole latency)
        "imu_latency_s": wire_time_s(rig.imu.rate_hz) + sim.truth.imu_latency_s,
        "imu_latency_std_s": IMU_WAKE_UP_STD_S,
        "imu_time_std_s": 0.0,
        # nothing moves the truth's nodes at random, and the filter's integration leaves
        # nothing (docs/estimator-noise.md#node-accelerations)
        "accel_psd_m2_s3": 0.0,
        "imu_rate_std_rad_s": std(emu.gyro_noise_density_rad_s_rthz * root, rate_count),
        # the bias is a random constant, not white noise: a state with its spread as prior
        "imu_accel_std_m_s2": std(accel_white, accel_count),
        "init_accel_bias_std_m_s2": emu.accel_bias_std_m_s2,
        "imu_angle_std_rad": std(emu.angle_noise_std_rad, angle_count),
        "init_gyro_bias_std_rad_s": max(emu.gyro_bias_std_rad_s, 1e-6),
        **rig_keys(rig),
        # the MX-12W emulator follows each goal through its position loop's lag (the P gain's)
        # at most at its moving speed (rig_keys' servo_speed_m_s) and reads its shaft to a
        # count; it serves a read, and takes a goal, within SERVO_BUS_SPAN_S of the host's
        # stamp: the read's time std, and through the lag a goal step's spread, std step x
        # time std / lag (docs/estimator-noise.md#the-servos)
        "servo_lag_s": lag_s,
        "servo_length_std_m": count_m / math.sqrt(12.0),
        "servo_time_std_s": time_std_s,
        "servo_step_std_ratio": time_std_s / lag_s,
        # where a run's ticks fall in that span is fixed for the run: its goals' mean delay is
        # off the fitted one by as much, a state (gyrohost.estimator.param_errors)
        "servo_delay_std_s": time_std_s,
        # a resting servo holds within its band of the command's count, and no walk beyond it
        # (docs/estimator-noise.md#the-servos)
        "rest_psd_m2_s": 0.0,
        "rest_hold_std_m": servo_hold_std(count_m, sim.servos.hold_band_steps),
        # the wheel board emulator's telemetry: the encoder's quantisation through the
        # firmware's low-pass (0.0146 rad/s RMS, docs/rig.md), in integer mrad/s on the wire
        # both ways (commands rounded, readings truncated)
        "wheel_speed_std_rad_s": 0.0146,
        "wheel_resolution_rad_s": 1.0e-3,
        # the emulated motors follow the board's ramped setpoint with their lag, erring from it
        # by a first-order Gauss-Markov process of that time constant: the lag model's walk
        # with the same stationary spread (2 std^2 / lag), at least MIN_WHEEL_WALK; the
        # reported speed trails theirs by the firmware's low-pass and the encoder's half tick
        "wheel_lag_s": wheels.time_constant_s,
        "wheel_accel_psd_rad2_s3": max(
            2.0 * wheels.speed_error_std_rad_s**2 / wheels.time_constant_s, MIN_WHEEL_WALK
        ),
        "wheel_filter_s": SPEED_FILTER_DELAY_S,
        # the board takes a command at its next tick and holds each step of the ramp for a
        # tick: the ramp starts where the frame came, give or take half a tick (uniform, the
        # tick / sqrt(12)); the pty brings the frame within a tenth of a millisecond of the
        # host's stamp, no delay worth a key (docs/estimator-noise.md#the-wheels)
        "wheel_delay_s": 0.0,
        "wheel_command_time_std_s": 1.0 / wp.TICK_HZ / math.sqrt(12.0),
        # a frame leaves when its bits have crossed the wire, fused at the board's own time
        # less that (wheel_wire_s, rig_keys'): it lies behind the sample by the loop's and the
        # reader's shortest wake-up, a tenth of a millisecond, as the IMU's grid
        "wheel_time_std_s": 0.0,
        "imu_frame_nodes": tuple(sim.truth.imu_frame_nodes),
        "imu_gravity_m_s2": tuple(sim.truth.imu_gravity_m_s2),
    }
