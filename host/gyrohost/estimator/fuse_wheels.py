"""Wheel speeds from the wheel board: ``z = omega_w - tau_f d omega_w/dt + v`` (rad/s, one per
wheel, about ``+b``).

The board reports its speed through a low-pass that trails a changing speed by ``tau_f``
(``wheel_filter_s``); the states are the wheels' own speeds, whose rate the process model gives
(linear in them: ``wheel_acceleration_slope``).

The telemetry's noise ``v`` is the encoder's quantisation through the firmware's low-pass: from
one sample to the next it is anticorrelated, so averaging cancels it faster than white noise of
the same variance. With ``wheel_noise_ma1 = theta`` it is a moving average of order one,
``v_k = a_k + theta a_{k-1}``, ``a_k`` white with ``var(v) = wheel_speed_std_rad_s^2``, and the
last sample's ``a`` is a state (``layout.wheel_noise``, one per wheel): each sample is fused with
``H = [I on omega_w, theta I on a]`` and noise ``var(a)``, then its own ``a_k``, estimated from
the same innovation (mean ``var(a) S^-1 y``, covariance ``var(a) - var(a)^2 S^-1``, cross
covariance ``-var(a) S^-1 H P`` with the posterior), replaces the state. ``theta = 0``: white.
"""

import math

import numpy as np
from scipy.special import erf

from .fusion import Innovation, Measurement, fuse

SOURCE = "wheels"


def white_std(config) -> float:
    """Std (rad/s) of the white term ``a`` of the wheel noise."""
    theta = config.wheel_noise_ma1
    return config.wheel_speed_std_rad_s / math.sqrt(1.0 + theta * theta)


def truncation(omega_rad_s, config):
    """Mean (n_w,) rad/s and slope (n_w,) of what the telemetry's truncation towards zero
    (step ``wheel_resolution_rad_s``) adds to speeds ``omega_rad_s`` (n_w,) rad/s.

    A reading ``omega + v`` (noise std ``wheel_speed_std_rad_s``, far above the step) loses
    on average half a step towards zero: ``-step/2 sign(omega + v)``, whose mean over ``v`` is
    ``-step/2 erf(omega / (std sqrt 2))``.
    """
    step, std = config.wheel_resolution_rad_s, config.wheel_speed_std_rad_s
    if step == 0.0:
        return np.zeros_like(omega_rad_s), np.zeros_like(omega_rad_s)
    a = omega_rad_s / std
    return -0.5 * step * erf(a / math.sqrt(2.0)), -step * np.exp(-0.5 * a * a) / (
        std * math.sqrt(2.0 * math.pi)
    )


def predict(ekf, x):
    """Predicted wheel speeds (n_w,) rad/s as the board reports them (through its low-pass, less
    the telemetry's truncation, :func:`truncation`) and the Jacobian (n_w, n)."""
    L, tau_f = ekf.layout, ekf.config.wheel_filter_s
    rate = ekf.process.wheel_acceleration(x[None, L.omega], ekf.u)[0]
    reported = x[L.omega] - tau_f * rate
    offset, slope = truncation(reported, ekf.config)
    H = np.zeros((L.n_wheels, L.size))
    H[:, L.omega] = np.diag((1.0 + slope) * (1.0 - tau_f * ekf.process.wheel_acceleration_slope()))
    hx = reported + offset
    if L.n_wheel_noise:
        theta = ekf.config.wheel_noise_ma1
        H[:, L.wheel_noise] = theta * np.eye(L.n_wheels)
        hx += theta * x[L.wheel_noise]
    return hx, H


def fuse_wheels(ekf, omega_rad_s) -> Innovation:
    """Fuse one telemetry sample of all wheel speeds (n_w,) rad/s.

    Its noise is the telemetry's white term (:func:`white_std`) plus, while the wheels change
    speed, the uncertainty of the sample's time stamp (``wheel_time_std_s``) through their rate
    of change, ``(d omega/dt)^2 wheel_time_std_s^2``, and what the low-pass taken as a delay
    leaves out where that rate bends: its response's next term, ``(tau_f^2 d^2 omega/dt^2)^2``
    (docs/estimator-noise.md#the-wheels), per wheel.
    """
    z = np.asarray(omega_rad_s, float)
    hx, H = predict(ekf, ekf.x)
    L, c = ekf.layout, ekf.config
    var_a = white_std(c) ** 2
    rate = ekf.process.wheel_acceleration(ekf.x[None, L.omega], ekf.u)[0]
    curve = c.wheel_filter_s**2 * ekf.process.wheel_jerk(rate)
    R = np.diag(var_a + (c.wheel_time_std_s * rate) ** 2 + curve**2)
    if not L.n_wheel_noise:
        return fuse(ekf, Measurement(SOURCE, z, hx, H, R))[0]
    P = ekf.P
    gain_a = var_a * np.linalg.inv(H @ P @ H.T + R)  # var(a) S^-1
    a_mean = gain_a @ (z - hx)
    a_cross = -gain_a @ H @ P
    a_var = var_a * np.eye(len(hx)) - var_a * gain_a
    result = fuse(ekf, Measurement(SOURCE, z, hx, H, R))[0]
    if not result.accepted:  # the sample's a is unknown: its prior, independent of the rest
        a_mean, a_cross = np.zeros_like(a_mean), np.zeros_like(a_cross)
        a_var = var_a * np.eye(len(hx))
    _replace_noise_state(ekf, a_mean, a_cross, a_var)
    return result


def _replace_noise_state(ekf, mean, cross, var):
    """Put the latest sample's ``a`` (mean (n_w,), cross covariance (n_w, n) with the state
    before the noise entries change, covariance (n_w, n_w)) in the noise states."""
    w = ekf.layout.wheel_noise
    P = ekf.P.copy()
    P[w, :] = cross
    P[:, w] = cross.T
    P[w, w] = var
    ekf.kf.x[w, 0] = mean
    ekf.kf.P = P
    ekf.constrain()  # the cross covariance onto the manifold's tangent space, as the update's
