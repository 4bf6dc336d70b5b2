"""The identified parameters' errors as states (:mod:`gyrohost.estimator.param_errors`): their
columns against the process step of a changed scene and against the servos' exact lag, the
covariance step against the augmented ``F P F^T`` written out, their layout and priors."""

import math
from dataclasses import replace

import numpy as np
import pytest

from gyrohost.estimator import TensegrityEKF
from gyrohost.estimator.config import EstimatorConfig, config_from_dict
from gyrohost.estimator.errors import EstimatorConfigError
from gyrohost.estimator.layout import from_model_state
from gyrohost.estimator.param_errors import (
    J3Response,
    ParamErrors,
    goal_delay_column,
    j3_column,
    string_columns,
)
from gyrohost.estimator.process_model import ProcessModel
from gyrotensegrity import Model, Stepper

LAG_S = 0.0133
STRINGS = ((4e-3, 1e-3), (1e-3, 2e-2))  # stiffness 6 %, damping 14 %, correlated
DELAY_STD_S = 3e-4
J3_VAR = 3e-3**2  # J3 known to 0.3 %


@pytest.fixture(scope="module")
def taut_state(model):
    """0.2 s into the paper's manoeuvre with the nodes at a tenth of their speed: the pulled
    string taut and shortening (its damping pulls) through a step, the other slack."""
    stepper = Stepper(model)
    for _ in range(20):
        stepper.step(0.01)
    u = model.input_at(stepper.t)
    x = from_model_state(model, stepper.x, u)
    x[3 * model.m : 6 * model.m] *= 0.1
    return x, u


def _scaled(model, factors):
    k, c = factors
    strings = [
        replace(s, stiffness=s.stiffness * k, damping=s.damping * c) for s in model.scene.strings
    ]
    return Model(replace(model.scene, strings=strings))


def _column_error(model, x, u, dt, which):
    """Largest error of a string column over a step of ``dt`` s against the step of the scene
    with that factor moved by 1e-5, relative to the step's response."""
    config = EstimatorConfig(servo_lag_s=LAG_S)
    process = ProcessModel(model, config)
    x_next, F = process.step(x, u, dt)
    column = string_columns(process, x, x_next, F, dt)[:, which]
    eps = 1e-5
    factors = [math.exp(eps) if i == which else 1.0 for i in range(2)]
    moved, _ = ProcessModel(_scaled(model, factors), config).step(x, u, dt)
    finite = (moved - x_next)[: 6 * model.m] / eps
    assert np.abs(finite).max() > 0.0
    return np.abs(column - finite).max() / np.abs(finite).max()


@pytest.mark.parametrize("which", [0, 1], ids=["stiffness", "damping"])
def test_the_string_columns_are_the_step_of_a_scene_with_the_factor_to_second_order(
    model, taut_state, which
):
    # the trapezoid rule over the step: its error falls fourfold as the step halves (and the
    # finite difference's, 1e-5 relative, is far below)
    x, u = taut_state
    coarse, fine = (_column_error(model, x, u, dt, which) for dt in (0.004, 0.002))
    assert 3.0 < coarse / fine < 5.0
    assert fine < 0.01


def _j3_column_error(model, x, u, dt):
    """Largest error of the J3 column over a step of ``dt`` s against the step of the scene
    with every wheel's J3 moved by 1e-5, relative to the step's response."""
    config = EstimatorConfig(servo_lag_s=LAG_S)
    process = ProcessModel(model, config)
    x_next, F = process.step(x, u, dt)
    column = j3_column(J3Response(process), x, x_next, F, u, dt)
    eps = 1e-5
    bars = [
        b if b.wheel is None else replace(b, wheel=replace(b.wheel, J3=model.J3[i] * math.exp(eps)))
        for i, b in enumerate(model.scene.bars)
    ]
    moved, _ = ProcessModel(Model(replace(model.scene, bars=bars)), config).step(x, u, dt)
    finite = (moved - x_next)[: 6 * model.m] / eps
    assert np.abs(finite).max() > 0.0
    return np.abs(column - finite).max() / np.abs(finite).max()


def test_the_j3_column_is_the_step_of_a_scene_with_the_factor_to_second_order(model, taut_state):
    # as the strings': the trapezoid rule's error falls fourfold as the step halves (J3_STEP's
    # forward difference, 1e-4 relative, lies below the finer step's)
    x, u = taut_state
    coarse, fine = (_j3_column_error(model, x, u, dt) for dt in (0.004, 0.002))
    assert 3.0 < coarse / fine < 5.0
    assert fine < 0.01


def test_the_goal_delay_column_is_the_exact_lags_response_at_a_goal_step(model, taut_state):
    x, u = taut_state
    process = ProcessModel(model, EstimatorConfig(servo_lag_s=LAG_S))
    L, dt = process.layout, 0.01
    step_m = np.array([2e-3, -1e-3])
    before = u.copy()
    u = u.copy()
    u[: L.n_strings] += step_m
    x_next, F = process.step(x, u, dt)
    column = goal_delay_column(process, x, x_next, u, before, F)
    # the lag's exact path with the goal step ``d`` late: the old goal for d, the new for dt - d
    r0, g0, g = x[L.rest], before[: L.n_strings], u[: L.n_strings]

    def rest_end(d):
        mid = g0 + (r0 - g0) * math.exp(-d / LAG_S)
        return g + (mid - g) * math.exp(-(dt - d) / LAG_S)

    exact = (rest_end(1e-7) - rest_end(0.0)) / 1e-7
    # the lean step's F_rr is the lag's exp(z), z = -dt / lag, to its RK4 polynomial
    z = -dt / LAG_S
    rk4 = 1.0 + z + z**2 / 2.0 + z**3 / 6.0 + z**4 / 24.0
    np.testing.assert_allclose(column, exact, rtol=2.0 * abs(rk4 / math.exp(z) - 1.0))
    held = goal_delay_column(process, x, x_next, u, u, F)
    np.testing.assert_allclose(held, 0.0, atol=1e-12 * np.abs(column).max())


def _filter(model, **keys):
    config = EstimatorConfig(servo_lag_s=LAG_S, **keys)
    return TensegrityEKF(model, config)


def test_the_covariance_step_is_the_augmented_f_p_f_t(model, taut_state):
    x0, u = taut_state
    ekf = _filter(model, string_cov_rel2=STRINGS, servo_delay_std_s=DELAY_STD_S, j3_var_rel2=J3_VAR)
    L = ekf.layout
    rng = np.random.default_rng(5)
    A = rng.normal(size=(L.size, L.size)) * 1e-3
    P = A @ A.T
    x = np.concatenate([x0, np.zeros(L.size - len(x0))])
    x[L.params] = [0.02, -0.05, 0.003, 1e-4]
    process, dt = ekf.process, 0.01
    x_next, F = process.step(x, u, dt)
    P_next = F @ P @ F.T
    params = ParamErrors(process, L)
    before = u.copy()
    before[: L.n_strings] -= [1e-3, 2e-3]  # a goal step at this step's start
    params.step(x, x_next, P_next, F, before, dt)  # the step before, under those goals
    got_x, got_P = params.step(x, x_next, P_next, F, u, dt)
    # the augmented Jacobian: F with the parameters' columns G
    cols = np.arange(L.params.start, L.params.stop)
    G = np.zeros((L.size, 4))
    G[: 6 * model.m, :2] = string_columns(process, x, x_next, F, dt)
    G[: 6 * model.m, 2] = j3_column(J3Response(process), x, x_next, F, u, dt)
    G[L.rest, 3] = goal_delay_column(process, x, x_next, u, before, F)
    F_aug = F.copy()
    F_aug[:, cols] += G
    np.testing.assert_allclose(got_x, x_next + G @ x[cols], rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(got_P, F_aug @ P @ F_aug.T, rtol=1e-9, atol=1e-18)


def test_the_keys_make_the_states_with_their_priors(model):
    ekf = _filter(model, string_cov_rel2=STRINGS, servo_delay_std_s=DELAY_STD_S, j3_var_rel2=J3_VAR)
    L = ekf.layout
    names = ["stiffness_error", "damping_error", "j3_error", "goal_delay_error_s"]
    assert ekf.layout.labels()[L.params] == names
    np.testing.assert_array_equal(ekf.P[L.string_errors, L.string_errors], STRINGS)
    assert ekf.P[L.j3_error, L.j3_error][0, 0] == pytest.approx(J3_VAR, rel=1e-15)
    assert ekf.P[L.goal_delay, L.goal_delay][0, 0] == DELAY_STD_S**2
    assert ekf.cycle is None  # the one-call IMU cycle has no room for them
    plain = _filter(model)
    assert plain.layout.size == L.size - 4 and plain.params is None
    assert _filter(model, j3_var_rel2=J3_VAR).layout.labels()[-1] == "j3_error"


def test_a_string_covariance_that_is_no_covariance_is_refused():
    with pytest.raises(EstimatorConfigError, match="'string_cov_rel2' must be symmetric"):
        config_from_dict({"string_cov_rel2": [[1e-3, 1e-4], [0.0, 1e-3]]})
    with pytest.raises(EstimatorConfigError, match="positive semi-definite"):
        config_from_dict({"string_cov_rel2": [[1e-3, 1e-2], [1e-2, 1e-3]]})
