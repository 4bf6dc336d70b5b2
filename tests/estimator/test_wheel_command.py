"""The filter's wheel states follow the wheel board's commands: the board's setpoint ramps at
ACCEL_RAD_S2 and the wheel trails it with a first-order lag; checked against the closed form of
a ramp through a first-order lag."""

import math

import numpy as np
from wheel_step import ACCEL, STEP, TAU_S, stepped_filter

from gyrohost.estimator import TensegrityEKF
from gyrohost.estimator.config import EstimatorConfig
from gyrohost.estimator.layout import layout_of


def closed_form(t, s0):
    """Speed at ``t`` s after the command steps from ``s0`` to ``s0 + STEP``."""
    ramp_s = STEP / ACCEL
    if t <= ramp_s:
        return s0 + ACCEL * (t - TAU_S * (1.0 - math.exp(-t / TAU_S)))
    at_end = closed_form(ramp_s, s0)
    return s0 + STEP - (s0 + STEP - at_end) * math.exp(-(t - ramp_s) / TAU_S)


def test_wheel_states_follow_the_ramped_command_through_the_lag(model):
    ekf, omega, s0 = stepped_filter(model)
    for t in (0.03, 0.11, 0.2, 0.4):
        ekf.advance(t)
        want = [np.sign(s) * (closed_form(t, abs(s)) - abs(s)) + s for s in s0]
        np.testing.assert_allclose(ekf.x[omega], want, atol=2e-3)


def test_without_a_lag_the_wheels_are_held_as_the_model_says(model):
    ekf = TensegrityEKF(model, EstimatorConfig())
    omega = layout_of(model).omega
    s0 = ekf.x[omega].copy()
    ekf.set_input(model.input_at(0.0)[: model.alpha], 0.0, s0 + 10.0)
    ekf.advance(0.2)
    np.testing.assert_allclose(ekf.x[omega], s0, atol=1e-9)


def test_a_wheel_delay_shifts_the_response_by_that_much(model):
    """With ``wheel_delay_s`` the response is the undelayed one, that much later."""
    delay = 0.02
    ekf, omega, s0 = stepped_filter(model, wheel_delay_s=delay)
    ekf.advance(delay)
    np.testing.assert_allclose(ekf.x[omega], s0, atol=1e-9)  # nothing yet
    for t in (0.035, 0.13, 0.3):
        ekf.advance(t)
        want = [np.sign(s) * (closed_form(t - delay, abs(s)) - abs(s)) + s for s in s0]
        np.testing.assert_allclose(ekf.x[omega], want, atol=2e-3)


def test_a_command_ahead_of_the_filter_waits_for_the_prediction(model):
    """A command stamped ahead of the filter (the run loop's, sent after the tick's fusion) is
    held until the prediction reaches it: a sample taken before it is predicted under the
    previous input, and the result equals predicting to the command's time first."""
    config = EstimatorConfig(servo_lag_s=0.01)
    rest = model.input_at(0.0)[: model.alpha]
    pulled = rest - 0.02
    held, first = TensegrityEKF(model, config), TensegrityEKF(model, config)
    held.set_input(pulled, 0.05)
    assert held.t == 0.0
    held.advance(0.03)  # a sample taken before the command
    np.testing.assert_array_equal(held.u[: model.alpha], rest)
    first.advance(0.03)
    np.testing.assert_array_equal(held.x, first.x)
    held.advance(0.08)
    first.advance(0.05)
    first.set_input(pulled, 0.05)
    first.advance(0.08)
    np.testing.assert_array_equal(held.u[: model.alpha], pulled)
    np.testing.assert_allclose(held.x, first.x, rtol=0, atol=1e-15)
    rest_states = held.x[layout_of(model).rest]
    assert np.all(rest_states < rest - 0.01)  # the rest lengths followed the pull
