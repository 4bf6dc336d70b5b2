"""The batched dynamics against the reference model; complex-step and closed-form Jacobians
against central finite differences (of the reference model's rhs where there is one) and
against each other."""

from dataclasses import replace

import numpy as np
import pytest
from filter_states import to_model_state

from gyrohost.estimator import TensegrityEKF, fuse_servos
from gyrohost.estimator.config import config_from_dict
from gyrohost.estimator.errors import EstimatorConfigError
from gyrohost.estimator.imu_prediction import predict_imu
from gyrotensegrity import Stepper, rhs

JACOBIANS = ("complex-step", "analytic")


def central(fun, x, columns, eps):
    cols = []
    for j in columns:
        e = np.zeros_like(x)
        e[j] = eps
        cols.append((fun(x + e) - fun(x - e)) / (2 * eps))
    return np.array(cols).T


def test_batched_dynamics_equals_reference_rhs(model, config, moving_state):
    x, x_model, u = moving_state
    ekf = TensegrityEKF(model, config, x0=x)
    L, ML = ekf.layout, model.layout
    f = ekf.process.derivative(x[None, : L.n_dynamic], u)[0]
    ref = rhs(0.0, x_model, u, model)
    assert np.max(np.abs(f[L.q_dot] - ref[ML.q_dot])) < 1e-12 * np.max(np.abs(ref[ML.q_dot]))


@pytest.mark.parametrize("jacobian", JACOBIANS)
def test_A_matches_finite_differences_of_reference_rhs(model, config, moving_state, jacobian):
    x, _, u = moving_state
    ekf = TensegrityEKF(model, replace(config, jacobian=jacobian), x0=x)
    L, ML = ekf.layout, model.layout
    _, A = ekf.process.linearise(x, u)
    cols = np.arange(L.q_dot.stop)  # positions and velocities (the model's own state entries)

    def ref(y):
        return rhs(0.0, to_model_state(model, y), u, model)[ML.q_dot]

    fd = central(ref, x.copy(), cols, 1e-7)
    err = np.max(np.abs(A[L.q_dot][:, cols] - fd)) / np.max(np.abs(fd))
    assert err < 1e-6, err


@pytest.mark.parametrize("jacobian", JACOBIANS)
def test_rk4_step_jacobian_matches_finite_differences(model, config, moving_state, jacobian):
    x, _, u = moving_state
    cfg = replace(config, process_method="rk4", rk4_substep_s=2.5e-3, jacobian=jacobian)
    ekf = TensegrityEKF(model, cfg, x0=x)
    x1, F = ekf.process.step(x, u, 0.01)
    fd = central(lambda y: ekf.process.step(y, u, 0.01)[0], x.copy(), range(x.size), 1e-7)
    assert np.max(np.abs(F - fd)) / np.max(np.abs(fd)) < 1e-6
    ref = Stepper(model, x0=to_model_state(model, x), max_dt=2.5e-3).step(0.01, u)
    assert np.max(np.abs(x1[: 2 * 3 * model.m] - ref[: 2 * 3 * model.m])) < 1e-12


def test_lean_step_close_to_reference_integration(model, config, moving_state):
    x, x_model, u = moving_state
    ekf = TensegrityEKF(model, config, x0=x)
    x1, _ = ekf.process.step(x, u, 0.01)
    ref = Stepper(model, x0=x_model, max_dt=1e-4).step(0.01, u)
    L = ekf.layout
    assert np.max(np.abs(x1[L.q] - ref[model.layout.q])) < 1e-5  # m
    assert np.max(np.abs(x1[L.q_dot] - ref[model.layout.q_dot])) < 1e-3  # m/s


def test_imu_and_servo_jacobians_match_finite_differences(model, config, moving_state):
    x, _, u = moving_state
    ekf = TensegrityEKF(model, config, x0=x)
    nd = ekf.layout.n_dynamic
    pred = predict_imu(ekf, x, u)
    for _value, jac, fun in (
        (pred.omega, pred.d_omega, lambda y: predict_imu(ekf, y, u).omega),
        (
            pred.specific_force,
            pred.d_specific_force,
            lambda y: predict_imu(ekf, y, u).specific_force,
        ),
        (pred.R_ws.ravel(), pred.dR_ws, lambda y: predict_imu(ekf, y, u).R_ws.ravel()),
    ):
        fd = central(fun, x.copy(), range(nd), 1e-7)
        assert np.max(np.abs(jac - fd)) <= 1e-6 * max(np.max(np.abs(fd)), 1.0)
    strings = np.arange(model.alpha)
    _, H = fuse_servos.predict(ekf, x, strings)
    fd = central(lambda y: fuse_servos.predict(ekf, y, strings)[0], x.copy(), range(x.size), 1e-7)
    assert np.max(np.abs(H - fd)) < 1e-7


def test_the_angle_rotation_jacobian_matches_finite_differences(model, config, moving_state):
    from scipy.spatial.transform import Rotation

    from gyrohost.estimator.fuse_imu_angle import rotation_jacobian

    x, _, u = moving_state
    ekf = TensegrityEKF(model, config, x0=x)
    pred = predict_imu(ekf, x, u)
    J = rotation_jacobian(pred.R_ws, pred.dR_ws)

    def turned(y):  # the rotation from the sensor axes at x to those at y, world axes
        return Rotation.from_matrix(predict_imu(ekf, y, u).R_ws @ pred.R_ws.T).as_rotvec()

    fd = central(turned, x.copy(), range(ekf.layout.n_dynamic), 1e-7)
    assert np.max(np.abs(J - fd)) < 1e-6 * max(np.max(np.abs(fd)), 1.0)


def manoeuvre_states(model, synthetic, moving_state):
    """Filter states along the synthetic manoeuvre (every 0.1 s) and the moving state, with
    their inputs (commanded rest lengths, the scene's wheel inputs)."""
    truth, _ = synthetic
    x, _, u = moving_state
    yield x, u
    for k in range(10, len(truth.t_s), 10):
        u = model.input_at(truth.t_s[k])
        u[: model.alpha] = truth.command[k]
        yield truth.x[k], u


@pytest.mark.parametrize("kink", ["sharp", "mean"])
def test_closed_form_linearisation_equals_complex_step(
    model, config, synthetic, moving_state, kink
):
    base = replace(config, kink_model=kink, rest_jitter_psd_m2_s=2e-10, jacobian="complex-step")
    cs = TensegrityEKF(model, base)
    cf = TensegrityEKF(model, replace(base, jacobian="analytic"))
    fields = ("dR_ws", "d_omega", "d_specific_force", "A", "x_dot", "specific_force")
    slack = set()
    for x, u in manoeuvre_states(model, synthetic, moving_state):
        s, _ = cs.process.string_lengths(x)
        slack.update(np.flatnonzero(s < x[cs.layout.rest]).tolist())
        p_cs, p_cf = predict_imu(cs, x, u), predict_imu(cf, x, u)
        for name in fields:
            ref, got = getattr(p_cs, name), getattr(p_cf, name)
            assert np.max(np.abs(got - ref)) <= 1e-8 * np.max(np.abs(ref)), name
        _, F_cs = cs.process.step(x, u, 0.01)
        _, F_cf = cf.process.step(x, u, 0.01)
        assert np.max(np.abs(F_cf - F_cs)) <= 1e-8 * np.max(np.abs(F_cs))
    assert slack, "some string should be slack at some state"


def test_closed_form_rk4_step_jacobian_equals_complex_step(model, config, moving_state):
    x, _, u = moving_state
    cfg = replace(config, process_method="rk4", rk4_substep_s=2.5e-3, jacobian="complex-step")
    x_cs, F_cs = TensegrityEKF(model, cfg).process.step(x, u, 0.01)
    x_cf, F_cf = TensegrityEKF(model, replace(cfg, jacobian="analytic")).process.step(x, u, 0.01)
    assert np.max(np.abs(x_cf - x_cs)) <= 1e-12 * np.max(np.abs(x_cs))
    assert np.max(np.abs(F_cf - F_cs)) <= 1e-8 * np.max(np.abs(F_cs))


def test_jacobian_key_is_checked():
    with pytest.raises(EstimatorConfigError, match="'jacobian'"):
        config_from_dict({"jacobian": "finite-differences"}, "x.toml")


def test_closed_form_jitter_columns_equal_complex_step(model, config, moving_state):
    x, _, u = moving_state
    cfg = replace(config, rest_jitter_psd_m2_s=2e-10, jacobian="complex-step")
    cs, cf = TensegrityEKF(model, cfg), TensegrityEKF(model, replace(cfg, jacobian="analytic"))
    _, F = cs.process.step(x, u, 0.01)
    margin = cs.process.tension_margins(x)[0]
    np.testing.assert_allclose(cf.process.tension_margins(x)[0], margin, rtol=0.0, atol=1e-15)
    G_cs = cs.process.taut_columns(0.01, F, x, margin)
    G_cf = cf.process.taut_columns(0.01, F, x, margin)
    assert np.max(np.abs(G_cf - G_cs)) <= 1e-8 * np.max(np.abs(G_cs))
