"""A servo's read off the rest length the strings pull with, while it moves
(``servo_time_std_s``): its noise grows by ``(servo_time_std_s d rest/dt)^2``, the rate the
model's first-order lag gives, ``(command - rest) / servo_lag_s``; a servo at rest reads with
``servo_length_std_m`` alone."""

import numpy as np
import pytest

from gyrohost.estimator import TensegrityEKF
from gyrohost.estimator.config import EstimatorConfig
from gyrohost.estimator.fuse_servos import fuse_servos

LAG_S, TIME_STD_S, LENGTH_STD_M = 0.005, 0.0015, 5e-5


def _read_variance(model, time_std_s, goal_step_m):
    """The innovation variance of one read of both strings, the goals ``goal_step_m`` (2,) m
    from the rest lengths (the filter's covariance of them taken out)."""
    config = EstimatorConfig(
        servo_lag_s=LAG_S,
        servo_time_std_s=time_std_s,
        servo_length_std_m=LENGTH_STD_M,
        rest_psd_m2_s=0.0,
    )
    ekf = TensegrityEKF(model, config)
    rest = ekf.x[ekf.layout.rest].copy()
    ekf.set_input(rest + np.asarray(goal_step_m), ekf.t)
    P_rest = np.diag(ekf.P)[ekf.layout.rest].copy()
    innovation = fuse_servos(ekf, rest, np.arange(model.alpha))
    return innovation.variance - P_rest


def test_a_moving_servo_reads_with_its_rate_times_the_time_std(model):
    step = np.array([1e-3, -3e-3])
    noise = _read_variance(model, TIME_STD_S, step)
    rate = step / LAG_S
    np.testing.assert_allclose(noise, LENGTH_STD_M**2 + (TIME_STD_S * rate) ** 2, rtol=1e-9)


@pytest.mark.parametrize("time_std_s, step", [(TIME_STD_S, [0.0, 0.0]), (0.0, [1e-3, -3e-3])])
def test_at_rest_or_without_the_key_the_read_has_its_length_noise_alone(model, time_std_s, step):
    noise = _read_variance(model, time_std_s, np.array(step))
    np.testing.assert_allclose(noise, LENGTH_STD_M**2, rtol=1e-9)
