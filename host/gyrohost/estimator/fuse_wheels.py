"""Wheel speeds from the wheel board: ``z = omega_w`` (rad/s, one per wheel, about ``+b``)."""

import numpy as np

from .fusion import Innovation, Measurement, fuse

SOURCE = "wheels"


def predict(ekf, x):
    """Predicted wheel speeds (n_w,) rad/s and the (linear) Jacobian (n_w, n)."""
    L = ekf.layout
    H = np.zeros((L.n_wheels, L.size))
    H[:, L.omega] = np.eye(L.n_wheels)
    return x[L.omega].copy(), H


def fuse_wheels(ekf, omega_rad_s) -> Innovation:
    """Fuse one telemetry sample of all wheel speeds (n_w,) rad/s.

    Its noise is the telemetry's (``wheel_speed_std_rad_s``) plus, while the wheels change
    speed, the uncertainty of the sample's time stamp (``wheel_time_std_s``) through their rate
    of change: ``(d omega/dt)^2 wheel_time_std_s^2`` per wheel.
    """
    hx, H = predict(ekf, ekf.x)
    L, c = ekf.layout, ekf.config
    rate = ekf.process.wheel_acceleration(ekf.x[None, L.omega], ekf.u)[0]
    R = np.diag(c.wheel_speed_std_rad_s**2 + (c.wheel_time_std_s * rate) ** 2)
    return fuse(ekf, Measurement(SOURCE, np.asarray(omega_rad_s, float), hx, H, R))[0]
