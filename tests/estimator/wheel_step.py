"""Test helper: a filter whose wheels, steady at their command, are commanded a speed step."""

import numpy as np

from gyrohost.estimator import TensegrityEKF
from gyrohost.estimator.config import EstimatorConfig
from gyrohost.estimator.layout import layout_of

TAU_S, ACCEL, STEP = 0.05, 100.0, 11.0  # lag s, ramp rad/s^2, step rad/s (ramp lasts 0.11 s)


def stepped_filter(model, **keys):
    """The filter (wheel lag ``TAU_S``, ramp ``ACCEL``, other keys ``keys``) at t = 0 with its
    wheels steady at their speeds ``s0`` (n_w,) rad/s and commanded ``STEP`` more in magnitude;
    returns (ekf, the wheels' slice of the state, s0)."""
    ekf = TensegrityEKF(model, EstimatorConfig(wheel_lag_s=TAU_S, wheel_accel_rad_s2=ACCEL, **keys))
    omega = layout_of(model).omega
    rest = model.input_at(0.0)[: model.alpha]
    s0 = ekf.x[omega].copy()
    ekf.set_input(rest, 0.0, s0)  # the wheels steady at their command
    ekf.set_input(rest, 0.0, s0 + STEP * np.sign(s0))
    return ekf, omega, s0
