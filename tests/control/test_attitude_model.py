"""The frozen-shape attitude model against the full model's simulation, the one-axis planner's
inertia and an analytic wheel turn; its right-hand side under the complex step."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyrohost.control import PlanError
from gyrohost.control.attitude_model import (
    MomentumParams,
    centre_of_mass,
    check_free,
    params_at,
    rhs,
)
from gyrohost.control.reduced import DBarReduced
from gyrohost.resources import shipped
from gyrotensegrity import BodyFrame, Model, load_scene, scene_from_dict
from gyrotensegrity.attitude import angle_between
from gyrotensegrity.compat import tomllib
from gyrotensegrity.simulate import Stepper


def rk4(x, u, params, duration_s, steps):
    h = duration_s / steps
    for _ in range(steps):
        k1 = rhs(0.0, x, u, params)
        k2 = rhs(0.0, x + 0.5 * h * k1, u, params)
        k3 = rhs(0.0, x + 0.5 * h * k2, u, params)
        k4 = rhs(0.0, x + h * k3, u, params)
        x = x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return x


def stiff_prism():
    """prism-rig with its strings 100 times stiffer: the same self-stressed shape (every force
    density scales alike), deformed 100 times less by a tumble."""
    data = tomllib.loads(shipped("scene", "prism-rig").read_text())
    for string in data["strings"]:
        string["stiffness"] *= 100.0
    return Model(scene_from_dict(data, "stiff-prism.toml"))


def test_a_stiff_prism_tumbles_as_the_rigid_body_its_momentum_gives():
    """Spinning wheels and a tumble about all three axes: the simulated attitude against the
    model's, which is exact for a rigid shape. The prism is not rigid: with ``eps`` the largest
    relative change of any node distance during the run, its inertia is off by O(eps) (its
    attitude by O(eps) per radian turned) and its frame's nodes wobble by O(eps) rad; the bound
    allows ten times that. Multiplying on the wrong side (world rates in ``q_dot``) misses by
    about 0.08 rad here."""
    model = stiff_prism()
    N0 = model.structure.N0
    arm = N0 - centre_of_mass(model, N0)[:, None]
    x0 = model.state(N0, np.cross([0.8, -0.5, 1.2], arm.T).T)
    u = model.input_at(0.0)
    stepper, frame = Stepper(model, x0=x0, max_dt=2e-5, fast=True), BodyFrame.of_model(model)
    pairs = np.triu_indices(N0.shape[1], 1)

    def distances(N):
        return np.linalg.norm(N[:, pairs[0]] - N[:, pairs[1]], axis=0)

    params = params_at(model, x0)
    x = np.concatenate([[1.0, 0.0, 0.0, 0.0], model.wheel_speeds(x0, u)])
    zero = np.zeros(len(model.wheel_bars))
    errors, eps = [], 0.0
    for _ in range(50):
        N, _ = model.nodes(stepper.step(0.02, u))
        eps = max(eps, float(np.max(np.abs(distances(N) / distances(N0) - 1.0))))
        x = rk4(x, zero, params, 0.02, 4)
        q_sim = frame.attitude(N).quaternion
        errors.append(angle_between(x[:4] / np.linalg.norm(x[:4]), q_sim))
    turn = float(angle_between(q_sim, [1.0, 0.0, 0.0, 0.0]))
    assert turn > 1.0
    assert max(errors) < 10.0 * eps * (1.0 + turn), (max(errors), eps, turn)


def test_one_wheel_spun_up_turns_the_body_back_about_a_fixed_axis():
    """From rest (no momentum), one wheel from 0 to 10 rad/s in 1 s: the body turns about the
    body axis ``I^-1 h`` (fixed: the turn keeps it), by ``-|I^-1 h| * 5 rad``."""
    model = Model(load_scene(shipped("scene", "dbar-gyro")))
    full = params_at(model, model.initial_state())
    params = MomentumParams(np.zeros(3), full.I_b, full.h_b[:, :1])
    x = rk4(np.array([1.0, 0.0, 0.0, 0.0, 0.0]), np.array([10.0]), params, 1.0, 200)
    assert x[4] == pytest.approx(10.0)
    axis = np.linalg.solve(full.I_b, full.h_b[:, 0])
    expected = Rotation.from_rotvec(-5.0 * axis).as_quat(scalar_first=True)
    assert angle_between(x[:4], expected) < 1e-9
    assert np.linalg.norm(5.0 * axis) > 1e-3  # six orders above the tolerance


def test_the_dbar_inertia_and_wheels_about_n2_n4_are_the_tilt_planners():
    """The body frame's y axis is the tilt axis; the D-bar is centred at its centre of mass."""
    model = Model(load_scene(shipped("scene", "dbar-gyro")))
    reduced = DBarReduced(model)
    params = params_at(model, model.initial_state())
    d = reduced.d_rest
    assert params.I_b[1, 1] == pytest.approx(float(reduced.inertia(d)), rel=1e-4)
    for j, e in enumerate(np.eye(len(model.wheel_bars))):
        assert params.h_b[1, j] == pytest.approx(float(reduced.wheel_momentum([d], e)[0]), rel=1e-4)


def test_the_complex_step_through_the_right_hand_side_gives_its_derivative():
    model = Model(load_scene(shipped("scene", "prism-rig")))
    params = params_at(model, model.initial_state())
    q = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_quat(scalar_first=True)
    x = np.concatenate([q, [60.0, -40.0, 25.0]])
    u = np.array([1.0, 2.0, -3.0])
    step = 1e-30
    for k in range(len(x)):
        e = np.zeros(len(x))
        e[k] = 1.0
        complex_step = np.imag(rhs(0.0, x + 1j * step * e, u, params)) / step
        central = (rhs(0.0, x + 1e-6 * e, u, params) - rhs(0.0, x - 1e-6 * e, u, params)) / 2e-6
        np.testing.assert_allclose(complex_step, central, rtol=1e-5, atol=1e-9)


def test_a_scene_held_from_outside_is_refused():
    with pytest.raises(PlanError, match="not conserved \\(fixed nodes, gravity\\)"):
        check_free(Model(load_scene(shipped("scene", "double-pendulum"))))
