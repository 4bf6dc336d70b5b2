"""The ``connect`` phase: the devices opened and checked, their versions logged."""

import numpy as np

from gyrohost.drivers.imu import Bwt61Driver
from gyrohost.drivers.servos import StringServoBus
from gyrohost.drivers.wheelboard import WheelBoard
from gyrohost.run.devices import WheelTelemetry
from gyrohost.run.errors import LimitBreach
from gyrohost.run.wheel_faults import clear_reported_faults


def connect_devices(loop) -> None:
    """Open the IMU (one sample read), the wheel board (handshake; faults latched before the
    run cleared and reported; telemetry rate and heartbeat set; its SPEED_MAX against the scene's
    and the schedule's spins) and the servo bus (pings), on ``loop`` (a ``RunLoop``).

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
    loop.servos = StringServoBus(cfg.servos).open()
    models = loop.servos.ping_all()
    versions = {
        "wheel_board": hello,
        "servo_models": models,
        "imu_first_sample_temperature_degC": first.temperature_degC,
    }
    loop.log.update_meta(devices=versions)
    loop.event("versions", f"wheel board fw {hello['fw_major']}.{hello['fw_minor']} "
               f"protocol v{hello['proto_version']}; servos {models}")  # fmt: skip
