"""Start-state check: after connect, before anything moves, the rig must be where the scene starts.

The estimator starts from the scene's initial state; a rig left elsewhere (the end state of an
earlier run against the same ``gyrotens rig``, a string not wound back) would have it reject
nearly every sample while the run goes on. So the measured state is compared with the scene's
initial state, each within its tolerance of the rig configuration's ``[start_check]`` table:

- IMU attitude: the angle between the measured and the expected vertical in sensor axes (roll
  and pitch; yaw is left out: the BWT61CL's yaw is relative, zeroed at power-on or by
  ``zero_yaw``). Expected: the sensor axes of the estimator's IMU attachment at the scene's
  initial nodes.
- IMU rate: the norm of the difference of the angular rates, rad/s (the gyro bias is in it).
  A scene that starts turning faster than this tolerance does not hold its initial attitude
  (the prism tumbles from its initial velocities): its attitude and rate are not compared, and
  the ``start_check`` event says so.
- Servo lengths: each servo's string length against the scene's rest length at t = 0.
- Wheel speeds: every board wheel at rest (the spin-up comes next).

Outside a tolerance the run is refused with :class:`StartStateRefused` (exit status 2, a user
error: put the rig back; the simulated rig takes ``reset`` on the standard input of
``gyrotens rig``).
"""

import math
import time
from dataclasses import dataclass

import numpy as np

from gyrohost.estimator.imu_model import ImuGeometry, euler_zyx
from gyrohost.run.errors import DeviceFault

from .errors import StartStateRefused


@dataclass(frozen=True)
class StartState:
    """The quantities compared (SI units).

    Attributes
    ----------
    roll_pitch_rad : ndarray, shape (2,), rad
        Roll and pitch of the sensor axes (Z-Y-X).
    omega_rad_s : ndarray, shape (3,), rad/s
        Angular rate in sensor axes.
    lengths_m : dict
        Servo name -> string length, m.
    wheels_rad_s : ndarray, shape (n,), rad/s
        Wheel speeds (board order).
    """

    roll_pitch_rad: np.ndarray
    omega_rad_s: np.ndarray
    lengths_m: dict
    wheels_rad_s: np.ndarray


def expected_state(loop) -> StartState:
    """The scene's initial state as the run's devices would measure it."""
    model = loop.model
    N, N_dot = model.nodes(model.initial_state())
    R_ws, omega = ImuGeometry(model, loop.estimator_config).frame(N[None], N_dot[None])
    lengths = {
        s.name: float(loop.rest0[loop.strings.index(string)])
        for s, string in zip(loop.config.servos.servo, loop.servo_strings, strict=True)
    }
    return StartState(euler_zyx(R_ws)[0, :2], omega[0], lengths, np.zeros(len(loop.spins)))


def measured_state(loop) -> StartState:
    """One IMU sample, one read of the servos and the first wheel telemetry from now on.

    Raises
    ------
    DeviceFault
        No wheel telemetry within the settings' ``wheel_silence_s``.
    """
    reader = loop.wheel_reader
    before = reader.latest
    sample = loop.imu.read_sample()
    servos = loop.servos.read_states()
    deadline = time.monotonic() + loop.settings.wheel_silence_s
    while reader.latest is before:
        if time.monotonic() > deadline:
            raise DeviceFault(
                "wheels", f"no telemetry within {loop.settings.wheel_silence_s:g} s of connect"
            )
        time.sleep(0.005)
    return StartState(
        np.asarray(sample.euler_rad[:2], float),
        np.asarray(sample.omega_rad_s, float),
        {s.name: s.length_m for s in servos},
        np.asarray(reader.latest.omega_rad_s, float),
    )


def _up(roll_pitch) -> np.ndarray:
    """The world's vertical in sensor axes, of roll and pitch (rad)."""
    roll, pitch = roll_pitch
    return np.array([-math.sin(pitch), math.sin(roll) * math.cos(pitch),
                     math.cos(roll) * math.cos(pitch)])  # fmt: skip


def differences(expected: StartState, measured: StartState, tol) -> tuple[list[str], list[str]]:
    """What is outside its tolerance, and what was not compared (messages).

    Parameters
    ----------
    expected, measured : StartState
    tol : StartCheckConfig
    """
    out, skipped = [], []
    turning = float(np.linalg.norm(expected.omega_rad_s))
    if turning > tol.rate_rad_s:
        skipped.append(
            f"IMU attitude and rate not compared: the scene starts turning at {turning:.3f} rad/s"
        )
    else:
        cos = float(np.dot(_up(expected.roll_pitch_rad), _up(measured.roll_pitch_rad)))
        off = math.acos(min(max(cos, -1.0), 1.0))
        if off > tol.attitude_rad:
            (r, p), (r0, p0) = measured.roll_pitch_rad, expected.roll_pitch_rad
            out.append(
                f"IMU attitude off by {off:.3f} rad (roll {r:+.3f}, pitch {p:+.3f} rad; the "
                f"scene starts at roll {r0:+.3f}, pitch {p0:+.3f} rad; tolerance "
                f"{tol.attitude_rad:g} rad)"
            )
        off = float(np.linalg.norm(measured.omega_rad_s - expected.omega_rad_s))
        if off > tol.rate_rad_s:
            w = ", ".join(f"{v:+.3f}" for v in measured.omega_rad_s)
            out.append(
                f"IMU rate off by {off:.3f} rad/s (measured ({w}) rad/s; tolerance "
                f"{tol.rate_rad_s:g} rad/s)"
            )
    for name, length in measured.lengths_m.items():
        want = expected.lengths_m[name]
        if abs(length - want) > tol.length_m:
            out.append(
                f"servo '{name}' string length {length:.4f} m, the scene starts at {want:.4f} m "
                f"(off by {length - want:+.4f} m; tolerance {tol.length_m:g} m)"
            )
    for i, speed in enumerate(measured.wheels_rad_s):
        if abs(speed - expected.wheels_rad_s[i]) > tol.wheel_speed_rad_s:
            out.append(
                f"wheel {i} turning at {speed:+.2f} rad/s, not at rest (tolerance "
                f"{tol.wheel_speed_rad_s:g} rad/s)"
            )
    return out, skipped


def check_start_state(loop) -> None:
    """Compare the measured state with the scene's initial state; log the outcome as a
    ``start_check`` event.

    Raises
    ------
    StartStateRefused
        Something is outside its tolerance (the message lists every difference).
    """
    found, skipped = differences(
        expected_state(loop), measured_state(loop), loop.config.start_check
    )
    if found:
        message = (
            "the rig is not in the scene's initial state, nothing moved: " + "; ".join(found)
            + ". Put it back (simulated rig: type 'reset' into gyrotens rig) and run again"
        )  # fmt: skip
        loop.event("start_check", message)
        raise StartStateRefused(message)
    loop.event("start_check", "; ".join(["within tolerances", *skipped]))
