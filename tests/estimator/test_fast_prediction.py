"""The compiled prediction step (estimator.fast_prediction) against the reference path
(ProcessModel.step, ProcessNoise.noise and filterpy's predict), to round-off.

Tolerances: the two paths do the same arithmetic in another order (the Taylor series nested
rather than summed from powers, BLAS products through the kernel rather than numpy); each
entry's round-off is a few ulp of the largest term it sums, ``|F| |P| |F|`` with ``|A dt|``
up to ~30, so relative to the largest entry some 1e-15 per step. 1e-10 leaves five orders of
margin for other CPUs' BLAS kernels and still fails on any wrong term (an error in one entry
of ``A`` changes ``P`` at the 1e-3 level)."""

from dataclasses import replace

import numpy as np
import pytest

from gyrohost.estimator import TensegrityEKF
from gyrohost.estimator.fast_prediction import fast_prediction
from gyrohost.estimator.imu_model import euler_zyx

RTOL = 1e-10
STEPS = 5


def pair(model, config, x0):
    """Two filters from the same start: the fast path and the reference."""
    fast = TensegrityEKF(model, config, x0=x0)
    ref = TensegrityEKF(model, config, x0=x0, fast=False)
    assert fast.fast_step is not None and ref.fast_step is None
    return fast, ref


def assert_equal_to_round_off(fast, ref):
    scale_x = np.max(np.abs(ref.x))
    assert np.max(np.abs(fast.x - ref.x)) <= RTOL * scale_x
    assert np.max(np.abs(fast.P - ref.P)) <= RTOL * np.max(np.abs(ref.P))


def shifted_rest(x, layout, shift_m):
    x = x.copy()
    x[layout.rest] += shift_m
    return x


@pytest.mark.parametrize("strings", ["as moving", "slack", "taut", "near the kink", "going taut"])
@pytest.mark.parametrize("jitter", [0.0, 2e-10])
@pytest.mark.parametrize("kink", ["sharp", "mean"])
def test_prediction_equals_reference(model, config, moving_state, strings, jitter, kink):
    """Strings taut, slack, (the mean kink's smooth part) within the jitter's std of their
    kink, where a lengthening string's force jumps, and going taut within the first step; the
    jitter of the SIL: its std per step 0.14 mm."""
    x, _, _ = moving_state
    fast, ref = pair(model, replace(config, rest_jitter_psd_m2_s=jitter, kink_model=kink), x)
    shift = {"as moving": 0.0, "slack": 0.05, "taut": -0.03}.get(strings)
    s_dot = ref.process.string_lengths(x)[1]
    if strings == "near the kink":  # each string's margin moved to 0.05 mm
        shift = ref.process.tension_margins(x)[0] - 5e-5
    elif strings == "going taut":  # slack by half a step's lengthening
        shift = ref.process.tension_margins(x)[0] + 0.005 * s_dot
    for ekf in (fast, ref):
        ekf.start_at(shifted_rest(x, ekf.layout, shift))
    margin = ref.process.tension_margins(ref.x)[0]
    want = {"slack": margin < 0.0, "taut": margin > 0.0, "near the kink": abs(margin) < 1e-4}
    assert want.get(strings, margin != 0.0).all()
    if strings in ("near the kink", "going taut"):  # one string's force jumps by its damping
        assert np.any(s_dot > 0.0)
    for _ in range(STEPS):
        fast.predict(0.01)
        ref.predict(0.01)
        assert_equal_to_round_off(fast, ref)


@pytest.mark.parametrize("kink", ["sharp", "mean"])
def test_prediction_with_the_imu_linearisation_equals_reference(model, config, moving_state, kink):
    """The lean step takes its A from the IMU prediction when there is one."""
    x, _, u = moving_state
    fast, ref = pair(model, replace(config, rest_jitter_psd_m2_s=2e-10, kink_model=kink), x)
    for ekf in (fast, ref):
        ekf._A = ekf.process.closed_form(ekf.x, u)[1]
        ekf.predict(0.004)
    assert_equal_to_round_off(fast, ref)


def test_prediction_with_commanded_wheels_equals_reference(model, config, moving_state):
    """Wheels that follow the board's ramping setpoints with a lag (the other wheel mode)."""
    x, _, _ = moving_state
    keys = {"wheel_lag_s": 0.013, "wheel_accel_rad_s2": 100.0, "rest_jitter_psd_m2_s": 2e-10}
    fast, ref = pair(model, replace(config, **keys), x)
    for ekf in (fast, ref):
        omega = ekf.x[ekf.layout.omega]
        ekf.set_input(ekf.u[: model.alpha], wheel_speed_rad_s=omega)
        ekf.set_input(ekf.u[: model.alpha], wheel_speed_rad_s=omega + 3.0)  # a 30 ms ramp
    for _ in range(STEPS):
        fast.predict(0.01)
        ref.predict(0.01)
        assert_equal_to_round_off(fast, ref)
    assert fast.process.wheel_acceleration_slope() != 0.0  # the wheels did follow the lag
    assert np.array_equal(fast.process.wheel_setpoint_rad_s, ref.process.wheel_setpoint_rad_s)


@pytest.mark.parametrize(
    "keys",
    [{"process_method": "rk4"}, {"jacobian": "complex-step"}],
)
def test_uncovered_configurations_take_the_reference_path(model, config, keys):
    ekf = TensegrityEKF(model, replace(config, **keys))
    assert ekf.fast_step is None
    assert fast_prediction(ekf.process, ekf.layout.size) is None


def test_the_kernels_own_loops_equal_blas(model, config, moving_state):
    """The kernel's products without BLAS (a build whose scipy hands no dgemm over): a
    prediction and an IMU fusion as with BLAS, to round-off."""
    from scipy.linalg import cython_blas

    from gyrotensegrity.fast import _fastkernel

    x, _, _ = moving_state
    config = replace(config, rest_jitter_psd_m2_s=2e-10)
    runs = []
    try:
        for dgemm in (None, cython_blas.__pyx_capi__["dgemm"]):
            _fastkernel.use_blas(dgemm)
            ekf = TensegrityEKF(model, config, x0=x)
            R, _ = ekf.attitude()
            ekf.fuse_imu(0.01, np.zeros(3), np.array([0.0, 0.0, 9.8]), euler_zyx(R[None])[0])
            runs.append(ekf)
    finally:
        _fastkernel.use_blas(cython_blas.__pyx_capi__["dgemm"])
    assert_equal_to_round_off(*runs)
