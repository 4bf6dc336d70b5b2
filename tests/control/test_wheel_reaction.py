"""Where a wheel's motor reaction goes, read from the scene's joints and rig fidelity."""

import pytest

from gyrohost.control import PlanError
from gyrohost.control.attitude_planner import AttitudePlanner
from gyrohost.control.shape_attitude import AttitudeModel
from gyrohost.control.wheel_reaction import wheel_couplings
from gyrohost.resources import shipped
from gyrotensegrity import Model, load_scene, scene_from_dict
from gyrotensegrity.compat import tomllib


def model_of(name, rig=None, wheel_torques=False):
    data = tomllib.loads(shipped("scene", name).read_text())
    if rig is not None:
        data["rig_fidelity"] = rig
    if wheel_torques:  # motor_reaction needs torque-driven wheels
        for bar in data["bars"]:
            if "wheel" in bar:
                bar["wheel"]["torque"] = 0.0
                bar["wheel"]["spin"] = float(bar["wheel"].get("spin", 0.0))
    return Model(scene_from_dict(data, f"{name}.toml"))


@pytest.mark.parametrize(
    "scene, rig, expected",
    [
        # bars meeting only strings, the paper's model: the reaction leaves the structure
        ("prism-rig", None, "lost"),
        ("prism-rig", {"joints": "ball", "stator_inertia": 1e-5}, "lost"),
        # the motor's reaction on a bar no hinge holds: it spins only that bar
        ("prism-rig", {"stator_inertia": 1e-5, "motor_reaction": True}, "own"),
        # hinged bars carry it to the structure
        ("dbar-rig", None, "body"),
    ],
)
def test_each_wheel_reaction_goes_where_the_joints_carry_it(scene, rig, expected):
    model = model_of(scene, rig, wheel_torques=bool(rig and rig.get("motor_reaction")))
    assert wheel_couplings(model) == (expected,) * len(model.wheel_bars)


def test_a_scene_without_rig_fidelity_takes_its_joined_bars_as_the_rigs_hinges():
    """dbar-gyro (the paper's model of the D-bar) plans for the hinged rig, dbar-rig."""
    model = Model(load_scene(shipped("scene", "dbar-gyro")))
    assert wheel_couplings(model) == ("body",) * 4


def test_wheels_that_only_spin_their_own_bars_are_held_by_the_planner():
    """Rig fidelity with the motor's reaction on the prism's unhinged bars: a spin change only
    spins the bar, so the planner does not move those wheels (wheels only: nothing to move)."""
    model = model_of("prism-rig", {"stator_inertia": 1e-5, "motor_reaction": True}, True)
    reduced = AttitudeModel(model, ["s7"])
    assert not reduced.steerable.any() and reduced.n_h == 0
    both = AttitudePlanner(reduced)
    assert list(both.active) == [0]  # the string only
    with pytest.raises(PlanError, match="nothing to move"):
        AttitudePlanner(reduced, mode="wheels")
