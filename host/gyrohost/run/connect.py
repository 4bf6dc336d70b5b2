"""The ``connect`` phase: the devices opened and checked, their versions logged."""

from dataclasses import replace

import numpy as np

from gyrohost.bringup.wheel_faults import clear_reported_faults
from gyrohost.drivers.imu import Bwt61Driver
from gyrohost.drivers.servos import StringServoBus
from gyrohost.drivers.wheelboard import WheelBoard
from gyrohost.estimator.config import speed_filter_delay_s
from gyrohost.run.devices import WheelTelemetry
from gyrohost.run.errors import LimitBreach

WHEEL_MODEL_PARAMS = ("ACCEL_RAD_S2", "SPEED_FILTER_SHIFT")
"""The board's parameters the estimator's wheel model repeats (its ramp and its low-pass)."""
FILTER_TOLERANCE_S = 0.5e-3  # half a tick: two shifts' delays lie a tick or more apart


def wheel_model_differences(board_params: dict, est) -> list[str]:
    """Where the estimator's model of the wheel board (``est``, an ``EstimatorConfig``) differs
    from the board's parameters ``board_params`` (name -> value, :data:`WHEEL_MODEL_PARAMS`),
    one line each naming the key to set; none where the wheels are held (``wheel_lag_s`` 0:
    the board's commands are not modelled)."""
    if est.wheel_lag_s == 0.0:
        return []
    out = []
    accel = board_params["ACCEL_RAD_S2"]
    if accel != est.wheel_accel_rad_s2:
        out.append(
            f"ACCEL_RAD_S2 is {accel} rad/s^2, the estimator's wheel_accel_rad_s2 "
            f"{est.wheel_accel_rad_s2:g}: set it to {accel} ([estimator] of the configuration)"
        )
    shift = board_params["SPEED_FILTER_SHIFT"]
    delay_s = speed_filter_delay_s(shift)
    if abs(delay_s - est.wheel_filter_s) > FILTER_TOLERANCE_S:
        out.append(
            f"SPEED_FILTER_SHIFT {shift} reports speeds {1e3 * delay_s:g} ms behind a ramp, "
            f"the estimator's wheel_filter_s is {1e3 * est.wheel_filter_s:g} ms: set it to "
            f"{delay_s:g} ([estimator] of the configuration)"
        )
    return out


def with_ports(config, ports: dict):
    """``config`` with device ports replaced: ``ports`` maps ``imu``, ``wheels``, ``servos`` to a
    path (a missing or ``None`` entry keeps the configured port)."""
    return replace(
        config,
        imu=replace(config.imu, port=ports.get("imu") or config.imu.port),
        wheelboard=replace(config.wheelboard, port=ports.get("wheels") or config.wheelboard.port),
        servos=replace(config.servos, port=ports.get("servos") or config.servos.port),
    )


def connect_devices(loop) -> None:
    """Open the IMU (one sample read), the wheel board (handshake; faults latched before the
    run cleared and reported; telemetry rate and heartbeat set; its SPEED_MAX against the scene's
    and the schedule's spins; its ramp and speed low-pass against the estimator's model, a
    notice where they differ) and the servo bus (pings), on ``loop`` (a ``RunLoop``).

    Raises
    ------
    LimitBreach
        A spin of the scene or the schedule beyond the board's SPEED_MAX.
    """
    cfg, s = loop.config, loop.settings
    loop.imu = Bwt61Driver(cfg.imu.port, baud=cfg.imu.baud, timeout_s=s.imu_silence_s).open()
    first = loop.imu.read_sample()
    loop.wheel_reader = WheelTelemetry(loop.queue, s.wheel_silence_s)
    loop.wheels = WheelBoard(cfg.wheelboard.port, on_telemetry=loop.wheel_reader.on_telemetry)
    hello = loop.wheels.connect()
    loop.final["wheel_faults_cleared"] = clear_reported_faults(loop.wheels, loop.notice)
    loop.wheel_reader.arm()
    loop.wheels.set_param("TELEMETRY_DIV", s.telemetry_div)
    loop.wheels.set_param("HEARTBEAT_MS", s.heartbeat_ms)
    speed_max = loop.wheels.get_param("SPEED_MAX_MRAD_S") / 1000.0
    scheduled = np.abs(loop.schedule.wheel_speed)
    fastest = max(np.max(np.abs(loop.spins)), np.max(scheduled, initial=0.0))
    if fastest > speed_max:
        raise LimitBreach(
            f"scene and schedule spins up to {fastest:.2f} rad/s exceed the wheel "
            f"board's SPEED_MAX {speed_max:.2f} rad/s"
        )
    board_params = {name: loop.wheels.get_param(name) for name in WHEEL_MODEL_PARAMS}
    for line in wheel_model_differences(board_params, loop.estimator_config):
        loop.notice(f"wheel board: {line}")
    loop.servos = StringServoBus(cfg.servos).open()
    models = loop.servos.ping_all()
    versions = {
        "wheel_board": hello,
        "wheel_board_params": board_params,
        "servo_models": models,
        "imu_first_sample_temperature_degC": first.temperature_degC,
    }
    loop.log.update_meta(devices=versions)
    loop.event("versions", f"wheel board fw {hello['fw_major']}.{hello['fw_minor']} "
               f"protocol v{hello['proto_version']}; servos {models}")  # fmt: skip
