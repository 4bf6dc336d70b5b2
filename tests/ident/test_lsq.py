"""The fits' local solve (:mod:`gyrohost.ident.lsq`) on residuals whose answer is known: the
Jacobian differences over each parameter's own step, also where the parameter is 0, and so
steps over a ripple that stops a solver differencing over scipy's relative steps."""

import numpy as np
import pytest
from scipy.optimize import least_squares

from gyrohost.ident import lsq

SMOOTH_MIN, RIPPLE_M, AMPLITUDE = 0.3, 1e-3, 0.01


def rippled(theta):
    """A smooth cost with its minimum at :data:`SMOOTH_MIN` under a ripple whose slope (63)
    is far steeper than the smooth cost's near its minimum: a fixed-step model's slack
    crossings."""
    x = theta[0]
    return np.array([x - SMOOTH_MIN, AMPLITUDE * np.sin(2.0 * np.pi * x / RIPPLE_M)])


def test_the_columns_difference_over_each_step_at_zero_in_one_batch():
    batches = []

    def batch(thetas):
        batches.append(len(thetas))
        return [np.array([t[0] ** 2, 3.0 * t[1]]) for t in thetas]

    J = lsq.forward_jacobian(batch, np.zeros(2), np.zeros(2), [0.1, 0.2])
    np.testing.assert_allclose(J, [[0.1, 0.0], [0.0, 3.0]], rtol=1e-12)
    assert batches == [2]


def test_a_rippled_cost_is_solved_to_its_smooth_minimum():
    sol = lsq.solve(
        rippled, lambda ts: [rippled(t) for t in ts], np.zeros(1), [0.05], [-1.0], xtol=1e-10
    )
    assert sol.x[0] == pytest.approx(SMOOTH_MIN, abs=0.01)
    # scipy's relative steps (sqrt(eps) at 0) read the ripple's slope and stop at its foot
    stuck = least_squares(rippled, np.zeros(1), diff_step=[0.05], bounds=([-1.0], np.inf))
    assert abs(stuck.x[0] - SMOOTH_MIN) > 0.1


def test_steps_must_be_positive():
    with pytest.raises(ValueError, match=r"steps must be positive, got \[0.1, 0.0\]"):
        lsq.solve(rippled, None, np.zeros(2), [0.1, 0.0], [-1.0, -1.0])


def test_a_start_on_a_lower_bound_still_moves():
    """A parameter fitted at its bound before (a latency at 0) starts the next fit there:
    scipy's trust region starts as wide as the start is long, and the start nudged 1e-10 off
    the bound made it 1e-15 wide, and every step was refused."""

    def quadratic(theta):
        return theta - np.array([0.04, 0.003])

    lower = np.array([-np.inf, -9.99988e-11])  # the second at its bound 0 (nominal 1e-10)
    sol = lsq.solve(
        quadratic, lambda ts: [quadratic(t) for t in ts], np.zeros(2), [1e-3, 2e-3], lower,
        xtol=1e-10,
    )  # fmt: skip
    np.testing.assert_allclose(sol.x, [0.04, 0.003], atol=1e-6)


def test_a_flat_direction_stops_at_its_ceiling():
    """A residual that falls on without end along one parameter (the likelihood's flat side in
    the node noise: a factor of 1e170 broke every run) ends at the upper bound; the other
    parameter still reaches its minimum. A start on the ceiling starts a step below it."""

    def falling(theta):
        return np.array([np.exp(-theta[0]), theta[1] - 0.2])

    for start in (0.0, 5.0):
        sol = lsq.solve(
            falling, lambda ts: [falling(t) for t in ts], np.array([start, 0.0]), [0.3, 0.01],
            [-np.inf, -np.inf], [5.0, np.inf], xtol=1e-10,
        )  # fmt: skip
        assert 5.0 - 1e-3 < sol.x[0] <= 5.0  # the trust region keeps strictly inside
        assert sol.x[1] == pytest.approx(0.2, abs=1e-6)


def test_the_node_noise_is_fitted_below_the_accelerometer_s_own_density():
    """The process-noise factor's ceiling: the accelerometer's white noise as a density; a
    nominal above it keeps its own value as the ceiling."""
    from dataclasses import replace

    from gyrohost.config import load_rig_config
    from gyrohost.estimator.config import for_rig
    from gyrohost.ident.params import parameters
    from gyrohost.resources import shipped
    from gyrotensegrity import load_scene

    config = load_rig_config(shipped("config", "sim-rig"))
    est = replace(for_rig(config), accel_psd_m2_s3=3e-8)  # a node noise to scale
    density = est.imu_accel_std_m_s2**2 / config.imu.rate_hz
    (p,) = parameters(load_scene(config.scene_path), config, ["process-noise"], 0.01, 1, est, True)
    assert p.value(p.upper) == pytest.approx(density, rel=1e-12)
    loud = replace(est, accel_psd_m2_s3=10.0 * density)
    (p,) = parameters(load_scene(config.scene_path), config, ["process-noise"], 0.01, 1, loud, True)
    assert p.upper == 0.0
