"""The rig-fidelity option: exact reduction to the paper's model, momentum through spin-up and
braking, the turn of the structure against the momentum balance, errors naming the key."""

import copy
from importlib.resources import files

import numpy as np
import pytest
from rigid_motion import structure_rate
from scipy.integrate import solve_ivp

from gyrotensegrity import Model, SceneError, Stepper, evaluate, rhs, scene_from_dict, simulate
from gyrotensegrity.errors import SceneError as ModelSceneError
from gyrotensegrity.fast import FastDynamics
from gyrotensegrity.scene import load_scene
from gyrotensegrity.textfile import read_toml

SCENES = files("gyrotensegrity") / "scenes"
BRAKE_S = 0.2  # s: spin-up and braking at constant torque take this long


def _dict(name):
    return read_toml(SCENES / f"{name}.toml", SceneError)


def dbar_rig_scene(case, damping=None, rig=None):
    """Variants of the shipped dbar-rig scene.

    case: "spin-up" (wheels from rest to 715 rpm in BRAKE_S at constant torque), "braking"
    (715 rpm to rest in BRAKE_S), "maneuver" (dbar-gyro's n1-n3 string maneuver, wheels at
    715 rpm).
    damping: string damping, N s/m (default the scene's); rig: the [rig_fidelity] table
    (default the scene's; False: none).
    """
    d = _dict("dbar-rig")
    if case == "maneuver":
        d["strings"] = [s for s in _dict("dbar-gyro")["strings"] if s["name"] == "s13"]
    J3 = 0.5 * 0.050 * 0.031**2
    for bar in d["bars"]:
        sign = np.sign(bar["wheel"]["spin"])
        spin = sign * 74.87462492
        bar["wheel"]["spin"] = 0.0 if case == "spin-up" else spin
        torque = {"spin-up": J3 * spin / BRAKE_S, "braking": -J3 * spin / BRAKE_S}.get(case, 0.0)
        bar["wheel"]["torque"] = {"t": [0.0, BRAKE_S, BRAKE_S + 1e-4], "value": [torque] * 2 + [0]}
    for s in d["strings"]:
        s["damping"] = s["damping"] if damping is None else damping
    if rig is False:
        del d["rig_fidelity"]
    elif rig is not None:
        d["rig_fidelity"] = rig
    return scene_from_dict(d, f"dbar-rig ({case})")


def states(model, duration_s, times):
    """States at ``times`` of a tight DOP853 run of the reference rhs."""
    sol = solve_ivp(
        lambda t, x: rhs(t, x, model.input_at(t), model),
        (0.0, duration_s),
        model.initial_state(),
        method="DOP853",
        rtol=1e-12,
        atol=1e-14,
        t_eval=times,
    )
    return sol.y.T


def momentum_balance_rate(model):
    """The turn (rad/s, about y) that takes up the wheels' initial momentum, from the structure's
    inertia about y through its centre (bars as rods with rotor J_1, stator axial inertia)."""
    sc, st = model.scene, model.structure
    N = st.N0
    B = N[:, st.bar_end] - N[:, st.bar_start]
    R = 0.5 * (N[:, st.bar_end] + N[:, st.bar_start])
    R = R - R.mean(axis=1, keepdims=True)
    d_y = B[1] / model.l
    J_perp = model.m_b * model.l**2 / 12.0 + model.J1
    I_y = np.sum(
        model.m_t * (R[0] ** 2 + R[2] ** 2) + J_perp * (1 - d_y**2) + sc.rig.stator_inertia * d_y**2
    )
    H_wheels = np.sum(model.J3 * model.spin0 * d_y)
    return H_wheels / I_y


def test_option_absent_or_inert_is_the_papers_model_exactly():
    base = Model(load_scene(SCENES / "dbar-gyro.toml"))
    d = _dict("dbar-gyro")
    d["rig_fidelity"] = {"joints": "ball", "stator_inertia": 0.0, "motor_reaction": False}
    inert = Model(scene_from_dict(d, "inert"))
    assert base.rig is None and inert.rig is None
    assert inert.layout == base.layout
    a = simulate(base, duration=0.05, rtol=1e-10, atol=1e-12)
    b = simulate(inert, duration=0.05, rtol=1e-10, atol=1e-12)
    assert np.array_equal(a["N"], b["N"]) and np.array_equal(a["omega_w"], b["omega_w"])


def test_ball_joints_with_stator_inertia_follow_the_paper_to_round_off():
    """An axial state with inertia but no torque and no hinge stays at rest and changes
    nothing: the rig path (multipliers for bar lengths, no Omega) matches Eqs. 62-68."""
    d = _dict("dbar-gyro")
    paper = Model(scene_from_dict(d, "paper"))
    d["rig_fidelity"] = {"stator_inertia": 1.2e-5}
    rig = Model(scene_from_dict(d, "stator"))
    assert rig.rig is not None and len(rig.rig.bars) == 4
    a = simulate(paper, duration=0.2, rtol=1e-11, atol=1e-13, fast=True)  # = reference
    b = simulate(rig, duration=0.2, rtol=1e-11, atol=1e-13)
    err = np.max(np.abs(a["N"] - b["N"]))
    print(f"ball joints + stator inertia vs the paper's model: {err:.1e} m")
    assert np.max(np.abs(a["N"][-1] - a["N"][0])) > 1e-3  # the maneuver moved the nodes
    assert err < 1e-10


@pytest.mark.parametrize("case", ["spin-up", "braking"])
def test_total_momentum_conserved_through_spin_up_and_braking(case):
    model = Model(dbar_rig_scene(case))
    times = np.linspace(0.0, BRAKE_S, 5)
    xs = states(model, BRAKE_S, times)
    H = np.array(
        [model.rig.angular_momentum(x, model.input_at(t)) for t, x in zip(times, xs, strict=True)]
    )
    wheels = np.max(np.abs(model.J3[0] * xs[:, model.layout.omega]).sum(axis=1))
    drift = np.max(np.linalg.norm(H - H[0], axis=1)) / wheels
    print(f"{case}: angular momentum drift {drift:.1e} of the wheels' {wheels:.2e} kg m^2/s")
    assert wheels > 5e-3  # the rotors carried their full momentum at one end
    assert drift < 1e-10


def test_braking_at_rest_turns_the_structure_as_the_momentum_balance_says():
    rig = Model(dbar_rig_scene("braking"))
    paper = Model(dbar_rig_scene("braking", rig=False))
    x = states(rig, BRAKE_S, [BRAKE_S])[-1]
    w = structure_rate(*rig.nodes(x))
    predicted = momentum_balance_rate(rig)
    print(f"turn after braking: {w[1]:.4f} rad/s, momentum balance {predicted:.4f} rad/s")
    assert abs(w[1] - predicted) < 1e-3 * abs(predicted)
    assert abs(predicted) > 0.5
    assert np.max(np.abs(w[[0, 2]])) < 1e-9
    still = states(paper, BRAKE_S, [BRAKE_S])[-1]
    assert np.max(np.abs(structure_rate(*paper.nodes(still)))) < 1e-9  # the paper's: no turn


def test_shipped_scene_uses_the_option_and_the_paper_paths_refuse_it():
    model = Model(load_scene(SCENES / "dbar-rig.toml"))
    assert model.rig is not None and len(model.rig.hinges) == 4
    with pytest.raises(ModelSceneError, match=r"dbar-rig.toml: rig_fidelity: .*FastRig"):
        FastDynamics(model)
    with pytest.raises(ModelSceneError, match="rig_fidelity"):
        evaluate(0.0, model.initial_state(), model.input_at(0.0), model)
    for fast in (False, True):  # the reference path and the option's kernel step it
        x = Stepper(model, max_dt=1e-3, fast=fast).step(0.01)
        assert x.shape == (model.layout.size,) and np.all(np.isfinite(x))


@pytest.mark.parametrize(
    ("table", "key"),
    [
        ({"joints": "slider"}, "rig_fidelity.joints: must be 'ball' or 'hinge'"),
        ({"stator_inertia": -1.0}, "rig_fidelity.stator_inertia: must be >= 0"),
        ({"motor_reaction": "yes"}, "rig_fidelity.motor_reaction: must be true or false"),
        ({"hinges": 1}, "rig_fidelity.hinges: unknown key"),
        ({"joints": "hinge"}, "rig_fidelity.stator_inertia: must be positive with hinge"),
        ({"motor_reaction": True}, "rig_fidelity.stator_inertia: must be positive"),
    ],
)
def test_bad_rig_fidelity_tables_name_the_key(table, key):
    d = _dict("dbar-gyro")
    d["rig_fidelity"] = table
    with pytest.raises(SceneError, match=key.replace(".", r"\.")):
        Model(scene_from_dict(d, "bad.toml"))


def test_motor_reaction_refuses_a_speed_controlled_wheel():
    d = _dict("dbar-gyro")
    d["rig_fidelity"] = {"stator_inertia": 1e-5, "motor_reaction": True}
    d["bars"][2]["wheel"]["spin"] = {"t": [0.0, 1.0], "value": [0.0, 10.0]}
    with pytest.raises(SceneError, match=r"motor_reaction: the wheel of bar b34 is speed-contr"):
        Model(scene_from_dict(d, "bad.toml"))


def test_hinge_needs_a_stator_on_each_bar_and_two_bars_per_node():
    d = _dict("dbar-gyro")
    d["rig_fidelity"] = {"joints": "hinge", "stator_inertia": 1e-5}
    del d["bars"][1]["wheel"]
    with pytest.raises(SceneError, match=r"bar b23 is at a hinge but carries no stator"):
        Model(scene_from_dict(d, "bad.toml"))
    d = _dict("dbar-gyro")
    d["rig_fidelity"] = {"joints": "hinge", "stator_inertia": 1e-5}
    d["bars"].append(copy.deepcopy(d["bars"][0]) | {"name": "b13", "nodes": ["n1", "n3"]})
    with pytest.raises(SceneError, match=r"node n1 joins 3 bars; a hinge joins two"):
        Model(scene_from_dict(d, "bad.toml"))


def test_collinear_bars_give_no_hinge_axis():
    d = _dict("double-pendulum")
    d["rig_fidelity"] = {"joints": "hinge", "stator_inertia": 1e-5}
    for bar in d["bars"]:
        bar["wheel"] = {"mass": 0.05, "radius": 0.03, "thickness": 0.01}
    names = list(d["nodes"])
    start = np.array(d["nodes"][d["bars"][0]["nodes"][0]])
    joint = np.array(d["nodes"][d["bars"][0]["nodes"][1]])
    end = d["bars"][1]["nodes"][1]
    d["nodes"][end] = (2 * joint - start).tolist()  # second bar in line with the first
    assert end in names
    with pytest.raises(SceneError, match=r"are collinear at node .*: no hinge axis"):
        Model(scene_from_dict(d, "bad.toml"))


def test_cli_runs_both_paths(tmp_path):
    from gyrohost.cli import main

    for flags in ([], ["--reference"]):
        out = str(tmp_path / f"r{len(flags)}.npz")
        assert main(["simulate", "dbar-rig", "--duration", "0.01", *flags, "-o", out]) == 0
