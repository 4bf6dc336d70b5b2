"""The BWT61CL's accelerometer calibration (``gyrotens imu calibrate``, docs/bring-up.md).

The IMU removes its accelerometer bias itself on the command ``FF AA 67`` while it lies level and
still (field notes, section 4). The host checks the still part first (a moving IMU would learn a
wrong bias), sends the command, waits and shows the mean specific force before and after.
"""

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .devices import Target
from .errors import SetupInputError

STILL_RAD_S = 0.02
"""Largest mean angular rate of a still IMU, rad/s: twice the gyro bias the datasheet gives after
power-up (0.5 deg/s = 0.0087 rad/s), so a resting sensor passes and a hand-held one does not."""

SAMPLE_WAIT_S = 1.0
"""Longest wait for one sample at the end of a window, s: twenty of the slower rate's periods
(20 Hz), so that a link that bunches samples is not taken for a silent IMU."""

Report = Callable[[str], None]


@dataclass(frozen=True)
class AccelCalibration:
    """Mean specific force before and after the calibration, m/s^2 (sensor axes)."""

    before_m_s2: np.ndarray
    after_m_s2: np.ndarray


def mean_motion(driver, window_s: float) -> tuple[np.ndarray, float]:
    """Mean specific force (m/s^2, sensor axes) and mean angular-rate magnitude (rad/s) of the
    samples of ``window_s`` seconds."""
    accel, rate = [], []
    deadline = time.monotonic() + window_s
    while time.monotonic() < deadline:
        sample = driver.read_sample(timeout_s=max(deadline - time.monotonic(), SAMPLE_WAIT_S))
        accel.append(sample.accel_m_s2)
        rate.append(float(np.linalg.norm(sample.omega_rad_s)))
    return np.mean(accel, axis=0), float(np.mean(rate))


def calibrate_accelerometer(
    target: Target, report: Report, window_s: float = 1.0, wait_s: float = 3.0
) -> AccelCalibration:
    """Calibrate the accelerometer of the IMU ``target`` names (its port and baud): the mean
    over ``window_s`` before, the command, ``wait_s`` for the IMU, the mean over ``window_s``.

    Raises
    ------
    SetupInputError
        The IMU is not still (nothing was sent).
    ImuError
        The port cannot be read, or no sample arrives.
    """
    from gyrohost.drivers.imu import Bwt61Driver

    imu = target.rig("imu").imu
    with Bwt61Driver(imu.port, imu.baud, timeout_s=imu.timeout_s) as driver:
        report(f"IMU on {imu.port}: keep it level and still")
        before, rate = mean_motion(driver, window_s)
        if rate > STILL_RAD_S:
            raise SetupInputError(
                f"the IMU turns at {rate:.3f} rad/s (still: below {STILL_RAD_S:g}): lay it down "
                "level and try again"
            )
        report(f"before: mean specific force {_vector(before)} m/s^2, |a| {_norm(before)}")
        driver.calibrate_accelerometer()
        time.sleep(wait_s)
        driver.poll()  # what arrived during the calibration is old
        after, _ = mean_motion(driver, window_s)
        report(f"after: mean specific force {_vector(after)} m/s^2, |a| {_norm(after)}")
    return AccelCalibration(before, after)


def _vector(v: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:+.3f}" for x in v) + ")"


def _norm(v: np.ndarray) -> str:
    return f"{float(np.linalg.norm(v)):.3f}"
