"""A stand-in host for rig runs (lighter than ``gyrotens run``): the three real drivers on the
rig's device paths, reading everything and commanding a little, counting what arrives.

Used by tests/rig/test_rig_cli.py; also runnable by hand next to ``gyrotens rig``::

    .venv/bin/python tests/rig/rig_host.py --duration 60 IMU_PATH WHEELS_PATH SERVOS_PATH
"""

import argparse
import subprocess
import sys
import time
from dataclasses import replace

from gyrohost.config import load_rig_config
from gyrohost.drivers.errors import ServoError
from gyrohost.drivers.imu import Bwt61Driver
from gyrohost.drivers.servos import StringServoBus
from gyrohost.drivers.wheelboard import WheelBoard
from gyrohost.resources import resolve

SPIN = 74.87462492  # rad/s, 715 rpm
SERVO_PERIOD_S = 0.02


def start_rig(cwd, *options: str, stdin=subprocess.DEVNULL) -> subprocess.Popen:
    """``gyrotens rig OPTIONS`` in a subprocess started in ``cwd``, its output as text pipes."""
    return subprocess.Popen(
        [sys.executable, "-m", "gyrohost", "rig", *options],
        stdin=stdin,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=cwd,
    )


def exercise(paths: dict[str, str], config_path: str, duration_s: float) -> dict[str, float]:
    """Drive the rig for ``duration_s`` s; return host-side rates (per second) and counts."""
    config = load_rig_config(resolve("config", config_path))
    telemetry = []
    imu = Bwt61Driver(paths["imu"]).open()
    wheels = WheelBoard(paths["wheels"], on_telemetry=telemetry.append)
    bus = StringServoBus(replace(config.servos, port=paths["servos"])).open()
    samples = reads = servo_errors = 0
    try:
        wheels.connect()
        # HEARTBEAT_LOST latches at boot when no host was there yet
        wheels.clear_faults(wheels.latched_faults())
        bus.configure()
        wheels.set_speeds([SPIN, -SPIN, -SPIN, SPIN])
        start = next_s = time.monotonic()
        while time.monotonic() - start < duration_s:
            samples += len(imu.poll())
            try:
                bus.read_states()
                reads += 1
            except ServoError:  # an injected overload or timeout: count it and go on
                servo_errors += 1
            wheels.heartbeat()  # this loop decides the wheel speeds: it keeps them alive
            next_s += SERVO_PERIOD_S
            time.sleep(max(next_s - time.monotonic(), 0.0))
        elapsed = time.monotonic() - start
    finally:
        wheels.close()
        bus.close()
        imu.close()
    return {
        "imu_samples_s": samples / elapsed,
        "telemetry_s": len(telemetry) / elapsed,
        "servo_reads_s": reads / elapsed,
        "servo_errors": servo_errors,
        "imu_bad_frames": imu.stats.corrupt_frames + imu.stats.dropped_frames,
        "telemetry_dropped": sum(wheels.decoder.dropped.values()),
        "last_speeds_rad_s": telemetry[-1].omega_rad_s if telemetry else None,
        "wheel_faults_at_end": wheels.faults,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("imu")
    parser.add_argument("wheels")
    parser.add_argument("servos")
    parser.add_argument("--config", default="sim-rig")
    parser.add_argument("--duration", type=float, default=10.0)
    args = parser.parse_args()
    paths = {"imu": args.imu, "wheels": args.wheels, "servos": args.servos}
    for key, value in exercise(paths, args.config, args.duration).items():
        print(f"{key}: {value}")


if __name__ == "__main__":
    main()
