"""The wheels' motor reaction in the filter's process model (``wheel_reaction = "body"``)."""

from dataclasses import replace

import numpy as np
import pytest

from gyrohost.estimator import TensegrityEKF
from gyrohost.estimator.errors import EstimatorConfigError
from gyrohost.resources import shipped
from gyrotensegrity import Model, diagnostics, load_scene

STEP = 1e-20
# commanded spins off the state's, so that every wheel changes speed (rad/s)
SPIN_CHANGE = np.array([30.0, -20.0, 10.0, 5.0])


def filters(model, config, x, jacobian="analytic"):
    """Filters with the paper's and the hinged rig's reaction, wheels speeding up."""
    out = {}
    for reaction in ("lost", "body"):
        cfg = replace(config, wheel_reaction=reaction, wheel_lag_s=0.05, jacobian=jacobian)
        ekf = TensegrityEKF(model, cfg, x0=x)
        ekf.process.command_wheels(x[ekf.layout.omega] + SPIN_CHANGE)
        out[reaction] = ekf
    return out


def momentum(model, dyn, L, y):
    """Total angular momentum (3,) about the centre of mass of a filter state ``y`` (complex
    safe): the structure's from the model, the wheels' spin ``J_3 omega b_hat`` added."""
    q, q_dot = y[L.q].reshape(3, -1), y[L.q_dot].reshape(3, -1)
    N, N_dot = dyn.N_fix + dyn.node_values(q), dyn.node_values(q_dot)
    mass = model.M_s.toarray()
    weights = mass.sum(axis=1) / mass.sum()
    c, c_dot = N @ weights, N_dot @ weights
    spins = np.zeros(dyn.n_wheels)
    body = diagnostics.angular_momentum(model, N - c[:, None], N_dot - c_dot[:, None], spins)
    B = (dyn.EE_T(q) + dyn.off)[:, dyn.wheel_bars]
    axes = B / np.sqrt((B * B).sum(axis=0))
    return body + (model.J3[dyn.wheel_bars] * y[L.omega] * axes).sum(axis=1)


def momentum_rate(ekf, x, u):
    """d(momentum)/dt along the filter's dynamics at ``x``: the complex step along ``f``."""
    L, dyn = ekf.layout, ekf.process.dyn
    f = ekf.process.derivative(x[None, : L.n_dynamic], u)[0]
    y = x[: L.n_dynamic] + 1j * STEP * f
    return momentum(ekf.process.model, dyn, L, y).imag / STEP


def test_the_hinged_rig_keeps_the_angular_momentum(model, config, moving_state):
    x, _, u = moving_state
    ekf = filters(model, config, x)
    L, dyn = ekf["lost"].layout, ekf["lost"].process.dyn
    spin_rate = ekf["lost"].process.derivative(x[None, : L.n_dynamic], u)[0][L.omega]
    B = (dyn.EE_T(x[L.q].reshape(3, -1)) + dyn.off)[:, dyn.wheel_bars]
    wheels = (model.J3[dyn.wheel_bars] * spin_rate * B / np.linalg.norm(B, axis=0)).sum(axis=1)
    scale = np.linalg.norm(wheels)
    assert scale > 1e-3  # the wheels do speed up
    # the paper's model loses the reaction: the total changes by the wheels' own change
    assert np.linalg.norm(momentum_rate(ekf["lost"], x, u) - wheels) < 1e-9 * scale
    # the hinged rig's: the structure turns the other way, the total stays
    assert np.linalg.norm(momentum_rate(ekf["body"], x, u)) < 1e-9 * scale


def test_the_turn_is_rigid_and_pushes_nothing_along(model, config, moving_state):
    x, _, u = moving_state
    ekf = filters(model, config, x)
    L, dyn = ekf["lost"].layout, ekf["lost"].process.dyn
    extra = [e.process.derivative(x[None, : L.n_dynamic], u)[0][L.q_dot] for e in ekf.values()]
    turn = (extra[1] - extra[0]).reshape(3, -1)
    q = x[L.q].reshape(3, -1)
    B, B_turn = (dyn.EE_T(q) + dyn.off)[:, : dyn.beta], dyn.EE_T(turn)[:, : dyn.beta]
    scale = np.abs(turn).max() * np.linalg.norm(B, axis=0).max()
    assert np.abs(turn).max() > 1e-3
    assert np.abs((B * B_turn).sum(axis=0)).max() < 1e-12 * scale  # bar lengths kept
    mass = model.M_s.toarray()
    push = dyn.node_values(turn) @ mass.sum(axis=1)  # the sum of the forces M a
    assert np.abs(push).max() < 1e-12 * np.abs(turn).max() * mass.sum()


def test_closed_form_linearisation_with_the_reaction_equals_complex_step(
    model, config, moving_state
):
    x, _, u = moving_state
    cf = filters(model, config, x)["body"]
    cs = filters(model, config, x, jacobian="complex-step")["body"]
    f_cf, A_cf = cf.process.linearise(x, u)
    f_cs, A_cs = cs.process.linearise(x, u)
    L = cf.layout
    assert np.abs(A_cs[L.q_dot, L.omega]).max() > 0.0  # the spins now turn the structure
    assert np.max(np.abs(f_cf - f_cs)) <= 1e-12 * np.max(np.abs(f_cs))
    assert np.max(np.abs(A_cf - A_cs)) <= 1e-8 * np.max(np.abs(A_cs))


def test_the_reaction_takes_the_reference_path(model, config, moving_state):
    x, _, _ = moving_state
    ekf = filters(model, config, x)
    assert ekf["lost"].fast_step is not None
    assert ekf["body"].fast_step is None and ekf["body"].cycle is None


def test_a_scene_whose_wheel_bars_meet_no_bar_is_refused(config):
    prism = Model(load_scene(shipped("scene", "prism-gyro")))
    with pytest.raises(EstimatorConfigError, match="'wheel_reaction'.*meet no other bar"):
        TensegrityEKF(prism, replace(config, wheel_reaction="body"))


def test_the_truth_sets_the_reaction_on_a_simulated_rig():
    from gyrohost.config import load_rig_config
    from gyrohost.estimator.config import for_rig
    from gyrohost.simrig.config import with_truth_scene

    rig = load_rig_config(shipped("config", "sim-rig"))
    assert for_rig(rig).wheel_reaction == "lost"
    assert for_rig(with_truth_scene(rig, shipped("scene", "dbar-rig"))).wheel_reaction == "body"
