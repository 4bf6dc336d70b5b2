"""An IMU sample's cycle in one kernel call (estimator.fast_cycle) against the same filter's
stages one by one (the other fast-path kernels) and against the reference path, to round-off.

Tolerances: those of test_fast_fusion (the update's arithmetic in another order than
filterpy's; 1e-8 of each quantity's size), which the cycle meets as the stages do: it runs
the same kernel functions in the same order."""

from dataclasses import replace

import numpy as np
import pytest
from test_fast_fusion import assert_same_filters, assert_same_results, imu_sample

from gyrohost.estimator import TensegrityEKF
from gyrohost.estimator.errors import EstimatorError
from gyrohost.estimator.fast_cycle import fast_cycle

SCENARIOS = {
    "sharp kink": {},
    "mean kink": {"kink_model": "mean", "rest_jitter_psd_m2_s": 2e-10},
    "accelerometer bias state": {"init_accel_bias_std_m_s2": 0.05, "imu_latency_s": 0.003},
    "commanded wheels": {"wheel_lag_s": 0.013, "wheel_accel_rad_s2": 100.0},
}


def three_filters(model, config, x):
    """The cycle, the stages (the cycle switched off) and the reference, from ``x``."""
    cycle = TensegrityEKF(model, config, x0=x)
    stages = TensegrityEKF(model, config, x0=x)
    stages.cycle = None
    ref = TensegrityEKF(model, config, x0=x, fast=False)
    assert cycle.cycle is not None and ref.cycle is None
    return cycle, stages, ref


def feed(ekf, omega_w, sample, tilt_rad):
    """IMU samples between wheel reports (steps split), a command due at one's time (the step
    to it not held), one behind the filter (fused with its lag, no step), the last tilted by
    ``tilt_rad``; every fusion's results."""
    ekf.set_input(ekf.u[: ekf.model.alpha] + 1e-4, 0.02 - ekf.config.imu_latency_s)
    results = []
    for t in (0.01, 0.02, 0.03):
        results.append(ekf.fuse_wheels(t - 0.004, omega_w))
        results.append(ekf.fuse_imu(t, *sample))
    ekf.advance(0.041)
    results.append(ekf.fuse_imu(0.038, *sample))
    tilted = sample[:2] + (sample[2] + np.array([0.0, tilt_rad, 0.0]),)
    results.append(ekf.fuse_imu(0.05, *tilted))
    return results


@pytest.mark.parametrize("tilt_rad", [0.002, np.radians(20.0)])
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_cycle_equals_stages_and_reference(model, config, moving_state, scenario, tilt_rad):
    """An accepted last sample and an outlier the angle's gate rejects (the others fused)."""
    x, _, _ = moving_state
    filters = three_filters(model, replace(config, **SCENARIOS[scenario]), x)
    omega_w = filters[2].x[filters[2].layout.omega] + 0.3
    if scenario == "commanded wheels":
        for ekf in filters:
            ekf.set_input(ekf.u[: model.alpha], wheel_speed_rad_s=omega_w - 0.3)
            ekf.set_input(ekf.u[: model.alpha], 0.005, wheel_speed_rad_s=omega_w + 3.0)
    sample = imu_sample(filters[2])
    cycle, taken = filters[0].cycle, []
    filters[0].cycle = lambda *args: taken.append(cycle(*args)) or taken[-1]
    runs = [feed(ekf, omega_w, sample, tilt_rad) for ekf in filters]
    assert len(taken) == 5 and None not in taken  # the cycle fused every IMU sample
    for other in runs[1:]:
        for got, want in zip(runs[0], other, strict=True):
            assert_same_results(got, want)
    for other in filters[1:]:
        assert_same_filters(filters[0], other)
        assert filters[0].t == other.t and filters[0].status == other.status
        assert [m.counters() for m in filters[0].monitors.values()] == [
            m.counters() for m in other.monitors.values()
        ]
    assert runs[0][-1][2].accepted == (tilt_rad < 0.1)


def test_a_refused_cycle_leaves_the_stages_to_say_why(model, config, moving_state):
    """A state the prediction cannot step (a non-finite velocity): the cycle refuses and the
    stages raise the filter's error, as on the reference path."""
    x, _, _ = moving_state
    errors = []
    for ekf in three_filters(model, config, x)[::2]:
        sample, bad = imu_sample(ekf), ekf.x.copy()
        bad[ekf.layout.q_dot.start] = np.inf
        ekf.kf.x = bad.reshape(-1, 1)
        with pytest.raises(EstimatorError) as caught:
            ekf.fuse_imu(0.01, *sample)
        errors.append((str(caught.value), ekf.t))
    assert errors[0] == errors[1]


def test_the_mounting_as_a_state_takes_the_stages(model, config):
    ekf = TensegrityEKF(model, replace(config, imu_mounting_std_rad=(0.01, 0.01, 0.02)))
    assert ekf.fast_imu is not None and fast_cycle(ekf, 1e-6) is None
