"""The attitude model with the shape: quasi-static shapes, their tables, the momentum balance,
against the one-axis planner's model and the full model's simulation."""

import numpy as np
import pytest
from prism_variants import prism
from scipy.spatial.transform import Rotation

from gyrohost.control import PlanError
from gyrohost.control.attitude_model import centre_of_mass
from gyrohost.control.reduced import DBarReduced
from gyrohost.control.shape_attitude import AttitudeModel, rotation_batch
from gyrohost.resources import shipped
from gyrotensegrity import BodyFrame, Model, diagnostics, load_scene
from gyrotensegrity.attitude import angle_between
from gyrotensegrity.simulate import Stepper


def rk4_step(am, x, u_of, t, h, H0):
    def f(tt, xx):
        return am.rhs(tt, xx, u_of(tt), H0)

    k1 = f(t, x)
    k2 = f(t + h / 2, x + h / 2 * k1)
    k3 = f(t + h / 2, x + h / 2 * k2)
    k4 = f(t + h, x + h * k3)
    return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


@pytest.fixture(scope="module")
def prism_model():
    return AttitudeModel(prism(), ["s7", "s8"])


def test_the_rest_lengths_give_back_the_scenes_equilibrium_and_its_tangent(prism_model):
    """prism-rig starts in its prestressed equilibrium: the Newton solve stays there; the
    implicit-function tangent matches central differences of solves (their error, O(h^2) with
    h = 1e-6 m on a shape of curvature O(1/m), is about 1e-10 m/m)."""
    shape, model = prism_model.shape, prism_model.model
    N, dN = shape.solve(shape.rest)
    assert np.max(np.abs(N - model.structure.N0)) < 1e-12
    r = shape.rest + np.array([-0.04, 0.02])
    N, dN = shape.solve(r, N)
    for j in range(2):
        e = np.eye(2)[j] * 1e-6
        central = (shape.solve(r + e, N)[0] - shape.solve(r - e, N)[0]) / 2e-6
        assert np.max(np.abs(central - dN[j])) < 1e-8


def test_the_table_interpolates_the_direct_solves(prism_model):
    """Catmull-Rom on 15 points per coordinate: O(h^3) with h / range = 1/14 is about 4e-4
    of a term's size; the bound allows ten times that (with the box's curvature)."""
    assert prism_model.table.interpolation_error(samples=6) < 4e-3


def test_the_dbar_with_wheels_fixed_lands_at_the_one_axis_planners_tilt():
    """n1-n3 from rest to 0.3 m and back in 4 s, wheels at their spins: the three-axis model
    turns about the frame's y by DBarReduced's tilt. Both tabulate the same closed form (one
    linearly on 401 points: relative error about (1.2 m / 400)^2 / (0.43 m)^2 = 5e-5); the
    bound is four times that; no turn about x or z (the D-bar's symmetric change)."""
    model = Model(load_scene(shipped("scene", "dbar-gyro")))
    am = AttitudeModel(model)
    assert am.names == ("s13", "s24")
    x, H0 = am.start(model.initial_state())
    d0, h = x[4], 0.01
    rate = (0.3 - d0) / 2.0
    for k in range(400):
        u = np.array([rate if k < 200 else -rate, 0.0, 0.0, 0.0, 0.0])
        x = rk4_step(am, x, lambda t, u=u: u, k * h, h, H0)
    turn = Rotation.from_quat(x[:4], scalar_first=True).as_rotvec()
    dbar = DBarReduced(model)
    t = np.linspace(0.0, 4.0, 4001)
    d = np.interp(t, [0.0, 2.0, 4.0], [d0, 0.3, d0])
    H_a = dbar.momentum(model.initial_state(), model.input_at(0.0))
    tilt = dbar.final_tilt(t, d, 0.0, H_a, model.spin0)
    assert abs(tilt) > 0.3
    assert turn[1] == pytest.approx(tilt, rel=2e-4)
    assert np.max(np.abs(turn[[0, 2]])) < 1e-12


def test_wheels_alone_keep_the_total_angular_momentum_where_their_reaction_reaches():
    """dbar-gyro (hinged bars carry the reaction, :mod:`.wheel_reaction`), its four wheels
    accelerated apart at the rest shape: the momentum of the rigid shape turning at the model's
    rate, from the full model's own diagnostics, stays the initial one (to the RK4 error, far
    below the wheels' change of J_3 * 80 rad/s)."""
    model = Model(load_scene(shipped("scene", "dbar-gyro")))
    am = AttitudeModel(model)
    assert am.couplings == ("body",) * 4 and am.n_h == 0
    x, H0 = am.start(model.initial_state())
    u = np.concatenate([np.zeros(am.a), [80.0, -50.0, 30.0, -20.0]])
    F0, N0 = am.frame.F0, model.structure.N0
    arm0 = N0 - centre_of_mass(model, N0)[:, None]
    worst = 0.0
    for k in range(100):
        x = rk4_step(am, x, lambda t: u, k * 0.01, 0.01, H0)
        w = am.body_rate(x, u, H0)
        R = F0 @ rotation_batch(x[:4]) @ F0.T  # world axes of the gauge
        arm = R @ arm0
        _, _, omega = am.split(x)
        H = diagnostics.angular_momentum(
            model, arm, np.cross(F0 @ rotation_batch(x[:4]) @ w, arm.T).T, omega
        )
        worst = max(worst, float(np.linalg.norm(F0.T @ H - H0)))
    assert angle_between(x[:4], [1.0, 0.0, 0.0, 0.0]) > 0.01  # the wheels turned it
    assert worst < 1e-9


def test_wheels_alone_turn_a_prism_nothing_as_in_the_full_model():
    """The prism's bars meet only strings, so its wheels' reactions leave it (the paper's
    model): spun up apart at the rest shape, the reduced model keeps it still and carries the
    wheels' momentum change in ``dH`` (RK4 exact: the rate is constant), and the full model,
    its wheels driven by the same motor torques for 1 s, does not turn either (it starts in
    its equilibrium; what moves it is that equilibrium's round-off, 1e-16 of the forces)."""
    model = prism(100.0)
    am = AttitudeModel(model, strings=[])
    assert am.couplings == ("lost",) * 3 and am.n_h == 3
    x, H0 = am.start(model.initial_state())
    u = np.array([80.0, -50.0, 30.0])
    for k in range(100):
        x = rk4_step(am, x, lambda t: u, k * 0.01, 0.01, H0)
    assert angle_between(x[:4], [1.0, 0.0, 0.0, 0.0]) < 1e-12
    F0, N0 = am.frame.F0, model.structure.N0
    arm0 = N0 - centre_of_mass(model, N0)[:, None]
    _, _, omega = am.split(x)
    H = F0.T @ diagnostics.angular_momentum(model, arm0, np.zeros_like(arm0), omega)
    np.testing.assert_allclose(H0 + x[-3:], H, rtol=0, atol=1e-12 * np.linalg.norm(H))
    assert np.linalg.norm(x[-3:]) > 0.5 * np.linalg.norm(H0)  # the momentum did change

    stepper = Stepper(model, max_dt=1e-3, fast=True)
    drive = model.input_at(0.0)
    drive[model.alpha :] = model.J3[model.wheel_bars] * u
    for _ in range(100):
        x_full = stepper.step(0.01, drive)
    np.testing.assert_allclose(model.wheel_speeds(x_full, drive), omega, rtol=1e-9)
    q = BodyFrame.of_model(model).attitude(model.nodes(x_full)[0]).quaternion
    assert angle_between(q, [1.0, 0.0, 0.0, 0.0]) < 1e-9


def test_the_complex_step_through_the_model_gives_its_derivative(prism_model):
    am = prism_model
    _, H0 = am.start(am.model.initial_state())
    q = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_quat(scalar_first=True)
    dH = [1e-4, -2e-4, 3e-4]  # the lost reactions' momentum
    x = np.concatenate([q, am.shape.rest + [-0.02, 0.01], [60.0, -40.0, 25.0], dH])
    u = np.array([0.01, -0.02, 1.0, 2.0, -3.0])
    for k in range(len(x)):
        e = np.eye(len(x))[k]
        cs = np.imag(am.rhs(0.0, x + 1e-30j * e, u, H0)) / 1e-30
        central = (am.rhs(0.0, x + 1e-7 * e, u, H0) - am.rhs(0.0, x - 1e-7 * e, u, H0)) / 2e-7
        np.testing.assert_allclose(cs, central, rtol=1e-5, atol=1e-9)


@pytest.mark.parametrize("spin_up", [(0.0, 0.0, 0.0), (40.0, 30.0, -50.0)])
def test_a_stiff_prism_changing_shape_turns_as_the_quasi_static_model_says(spin_up):
    """Two vertical strings shortened by 5 cm out of phase and back in 2 s (smooth), wheels at
    +-150 rad/s, held or spun up (rad/s^2, by their motors' torques): the full model (strings
    100 times stiffer than prism-rig's, so the shape follows its equilibrium) turns as the
    reduced model. The gap is the shape's dynamic lag and the frame nodes' ringing, second order
    in the drive's frequency over the strings' (docs/attitude-plans.md gives the figure); the
    bound is 10 % of the turn. Leaving out the shape connection ``B_b`` (the shape change's own
    momentum) misses by more, and so does letting the spin-up's reaction turn the body (it
    leaves the prism: :mod:`.wheel_reaction`), by far more (the docs give both figures)."""
    model = prism(100.0, [150.0, -150.0, 150.0])
    am = AttitudeModel(model, ["s7", "s8"])
    x0_full = model.initial_state()
    x, H0 = am.start(x0_full)
    T, A, dt, sub = 2.0, 0.05, 0.01, 10
    rest, spin_up = am.shape.rest, np.array(spin_up)

    def r_of(t):
        second = np.sin(np.pi * np.clip(t - T / 4, 0.0, T / 2) / (T / 2)) ** 2
        return rest - A * np.array([np.sin(np.pi * t / T) ** 2, second])

    def u_of(t):
        return np.concatenate([(r_of(t + 1e-6) - r_of(t - 1e-6)) / 2e-6, spin_up])

    stepper, frame = Stepper(model, x0=x0_full, max_dt=2e-5, fast=True), BodyFrame.of_model(model)
    errors = []
    for k in range(int(T / dt)):
        x = rk4_step(am, x, u_of, k * dt, dt, H0)
        for j in range(sub):
            u = model.input_at(0.0)
            u[[6, 7]] = r_of((k + (j + 0.5) / sub) * dt)
            u[model.alpha :] = model.J3[model.wheel_bars] * spin_up
            x_full = stepper.step(dt / sub, u)
        N, _ = model.nodes(x_full)
        errors.append(angle_between(x[:4] / np.linalg.norm(x[:4]), frame.attitude(N).quaternion))
    turn = angle_between(x[:4], [1.0, 0.0, 0.0, 0.0])
    assert turn > 0.005
    assert max(errors) < 0.1 * turn, (max(errors), turn)


def test_more_than_three_actuated_strings_are_refused():
    with pytest.raises(PlanError, match="at most 3"):
        AttitudeModel(prism(), ["s1", "s2", "s3", "s7"])


def test_a_scene_its_strings_cannot_hold_is_refused_naming_it():
    """dbar-rig: one string across a rhombus of ball-jointed bars (its hinges are rig fidelity,
    not statics) folds freely: no quasi-static shape."""
    model = Model(load_scene(shipped("scene", "dbar-rig")))
    with pytest.raises(PlanError, match="dbar-rig: at its rest lengths, its strings hold no shape"):
        AttitudeModel(model)
