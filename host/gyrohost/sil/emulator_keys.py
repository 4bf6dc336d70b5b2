"""The EKF's settings for the simulated rig, derived from its emulators and its truth.

A run on the simulated rig takes its ``[estimator]`` table like any rig (the shipped
``sim-rig`` configuration writes these values out; a test keeps them equal); the in-process
SIL and the studies start from :func:`emulator_keys` itself, so that a changed emulator
setting reaches their filter.
"""

import math

from gyrohost.config import LOOP_RATE_HZ, RigConfig
from gyrohost.drivers.mx12 import steps_per_metre
from gyrohost.estimator.config import (
    MIN_WHEEL_WALK,
    SPEED_FILTER_DELAY_S,
    imu_keys,
    imu_wire_counts,
    sawtooth_psd,
    servo_hold_std,
)
from gyrohost.simrig.config import sim_config


def emulator_keys(rig: RigConfig) -> dict:
    """The EKF's keys describing the simulated rig of ``rig`` (its ``[sim]`` tables): the noise
    of its emulated devices, the attachment of its IMU, the steps of its truth, with the
    :func:`~gyrohost.estimator.config.imu_keys` of its ``[imu]`` table.

    White noise std = density * sqrt(rate / 2), combined with the quantisation of the wire
    format (one count / sqrt(12)); the accelerometer's bias (no state of the filter: calibrate
    it away with ``FF AA 67`` where possible) is folded into its noise. Returns a dict for
    :func:`config_from_dict`.
    """
    rate_count, accel_count, angle_count = imu_wire_counts()
    root = math.sqrt(rig.imu.rate_hz / 2.0)
    sim = sim_config(rig)
    emu = sim.imu

    def std(white, count, bias=0.0):
        return math.sqrt(white**2 + count**2 / 12.0 + bias**2)

    accel_white = emu.accel_noise_density_m_s2_rthz * root
    wheels = sim.wheels
    return {
        # the grid the host rebuilds from the earliest arrivals lies this much after the
        # samples: the truth's step computed before the sample goes out, then the pty and the
        # reader thread, so it depends on the machine (the positions' NEES fits best at 1.5 ms
        # on one, 0.8 ms on a faster one, and rises by about 10 per ms off in the fastest
        # turn): the middle, with its spread as the samples' time uncertainty
        # (docs/estimator-noise.md#the-imus-latency-depends-on-the-machine)
        "imu_latency_s": 0.0012,
        "imu_time_std_s": 0.001,
        # the node accelerations' noise: the servos' goal steps and the loop's late ticks,
        # which the in-process SIL's 3e-8 does not see; 5e-7 holds the NEES mid-bounds on three
        # idle batches scored from drawn starts, 1e-7 leaves it at the upper bound and 2e-6
        # at the lower (reports/estimator-history.md#scored-from-drawn-starts)
        "accel_psd_m2_s3": 5.0e-7,
        "imu_rate_std_rad_s": std(emu.gyro_noise_density_rad_s_rthz * root, rate_count),
        # the bias is a random constant, not white noise: a state with its spread as prior
        "imu_accel_std_m_s2": std(accel_white, accel_count),
        "init_accel_bias_std_m_s2": emu.accel_bias_std_m_s2,
        "imu_angle_std_rad": std(emu.angle_noise_std_rad, angle_count),
        "init_gyro_bias_std_rad_s": max(emu.gyro_bias_std_rad_s, 1e-6),
        **imu_keys(rig),
        # the MX-12W emulator moves to each tick's goal at up to its max_speed_m_s: on the
        # paper's pulls a first-order lag of 5 ms of the tick's command on average; within the
        # tick it covers the goal step and holds, so it strays from the lag by up to the step,
        # a position spread uniformly over it (std step / sqrt(12)) that the rest lengths keep
        # while they move; holding still, they sit within the hold below
        # (docs/estimator-noise.md#resting-servos)
        "servo_lag_s": 0.005,
        # at rest it reads within a count of where it holds, and 5e-5 m left for the rest put
        # the servo NIS at 1.8-2.0 of 2 on three real-time batches (2e-4: 0.87-1.06, below its
        # bounds on one; docs/estimator-noise.md#the-servos-reads-moving-and-at-rest)
        "servo_length_std_m": 5.0e-5,
        "servo_step_std_ratio": 1.0 / math.sqrt(12.0),
        # a resting servo holds within its band of the command's count, and no walk beyond it
        # (1e-7 kept 15-23 um at rest where the truth stays within 6 um, the rest block near 0;
        # docs/estimator-noise.md#resting-servos)
        "rest_psd_m2_s": 0.0,
        "rest_hold_std_m": servo_hold_std(
            max((1.0 / steps_per_metre(s) for s in rig.servos.servo), default=0.0),
            sim.servos.hold_band_steps,
        ),
        # the strings see their rest lengths in steps about the filter's continuous ones, which
        # the kink rectifies: the servos' goal steps, one per tick of the run loop, each covered
        # at the servo's speed (the fastest servo's: the largest steps;
        # docs/estimator-noise.md#the-rest-length-jitter)
        "rest_jitter_psd_m2_s": sawtooth_psd(
            1.0 / LOOP_RATE_HZ,
            max((s.max_speed_m_s for s in rig.servos.servo), default=math.inf),
        ),
        "kink_model": "mean",
        # the wheel board emulator's telemetry: the encoder's quantisation through the
        # firmware's low-pass (0.0146 rad/s RMS, docs/rig.md), in integer mrad/s on the wire
        # both ways (commands rounded, readings truncated)
        "wheel_speed_std_rad_s": 0.0146,
        "wheel_resolution_rad_s": 1.0e-3,
        # the emulated motors follow the board's ramped setpoint with their lag, erring from it
        # by a first-order Gauss-Markov process of that time constant: the lag model's walk
        # with the same stationary spread (2 std^2 / lag), at least MIN_WHEEL_WALK; the
        # reported speed trails theirs by the firmware's low-pass
        "wheel_lag_s": wheels.time_constant_s,
        "wheel_accel_psd_rad2_s3": max(
            2.0 * wheels.speed_error_std_rad_s**2 / wheels.time_constant_s, MIN_WHEEL_WALK
        ),
        "wheel_filter_s": SPEED_FILTER_DELAY_S,
        # with the loop on time the telemetry of a speed step starts when the lags alone say:
        # a delay of 20 ms (what a late loop showed) puts the model behind the board through
        # every ramp (docs/estimator.md#wheel-commands)
        "wheel_delay_s": 0.0,
        # its frames arrive 0-11 ms after they were taken, but are fused at the board's own
        # time (wheel_times "device"), late by the link's shortest delay (about 1 ms): 2 ms (0:
        # the wheel states overconfident in some ramps; 10 ms while they were fused at arrival,
        # docs/estimator.md)
        "wheel_time_std_s": 0.002,
        # the host stamps a command when it sends it; the emulated board acts on it when the
        # rig's loop next serves its pty, between the truth's steps, which on a loaded two-core
        # machine is up to a step later: uniform over the step, dt / sqrt(12) (without it the
        # wheel-steps run test lost the wheels in two of four loaded suites)
        "wheel_command_time_std_s": sim.truth.dt_s / math.sqrt(12.0),
        "imu_frame_nodes": tuple(sim.truth.imu_frame_nodes),
        "imu_gravity_m_s2": tuple(sim.truth.imu_gravity_m_s2),
    }
