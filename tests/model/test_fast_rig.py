"""The rig-fidelity kernel (gyrotensegrity.fast_rig) against the reference right-hand side."""

from importlib.resources import files

import numpy as np
import pytest

from gyrotensegrity import Model, SceneError, Stepper, scene_from_dict
from gyrotensegrity.fast_rig import FastRig
from gyrotensegrity.scene import load_scene
from gyrotensegrity.textfile import read_toml

SCENES = files("gyrotensegrity") / "scenes"

TOL = 1e-9
"""Relative to the largest derivative. The multipliers come from K = G M^-1 G^T, whose nonzero
eigenvalues spread over about five decades (the stators' 1/J_s = 8e4 kg^-1 m^-2 against the
nodes' ~10 1/kg), so round-off of 1e-16 may grow to ~1e-11 in them; the margin leaves two
decades more and is still far below any modelling term (the motor reaction, the hinge torques)."""

VARIANTS = {
    "dbar-rig": {},
    "follower string s24": {"s24": True},
    "speed wheels, no reaction": {"rig": {"motor_reaction": False}, "speed": True},
    "ball joints, stators": {"rig": {"joints": "ball"}},
}


def variant(name):
    """dbar-rig with the changes of :data:`VARIANTS`; torque-driven wheels without schedules
    (the test sets the torques) unless ``speed``."""
    opts = VARIANTS[name]
    d = read_toml(SCENES / "dbar-rig.toml", SceneError)
    d["rig_fidelity"].update(opts.get("rig", {}))
    if opts.get("s24"):
        d["strings"].append(dict(d["strings"][0], name="s24", nodes=["n2", "n4"]))
    for bar in d["bars"]:
        wheel = bar["wheel"]
        del wheel["torque"]
        if opts.get("speed"):
            wheel["spin"] = {"t": [0.0, 1.0], "value": [wheel["spin"]] * 2}
    return Model(scene_from_dict(d, f"dbar-rig ({name})"))


def trajectory(model, steps=20, seed=0):
    """States and inputs of the reference stepped under a pulled string and random torques
    (wheel speeds): states that keep the constraints, as the truth's do."""
    rng = np.random.default_rng(seed)
    stepper = Stepper(model, max_dt=1e-3)
    u = model.input_at(0.0)
    u[0] -= 0.02
    for _ in range(steps):
        tq = rng.normal(scale=2e-3, size=len(model.torque_wheels))
        u[model.alpha + model.torque_wheels] = tq
        u[model.alpha + model.speed_wheels] += rng.normal(scale=5.0, size=len(model.speed_wheels))
        yield stepper.step(0.005, u), u.copy()


@pytest.mark.parametrize("name", list(VARIANTS))
def test_kernel_matches_the_reference(name):
    model = variant(name)
    fast = FastRig(model)
    assert fast.kernel is not None
    for x, u in trajectory(model):
        ref = model.rig.rhs(0.1, x, u)
        assert np.abs(fast.rhs(0.1, x, u) - ref).max() <= TOL * np.abs(ref).max()


def test_fast_stepper_follows_the_reference_stepper():
    """Stepper(fast=True) takes the kernel for a rig-fidelity scene (the dbar-rig braking)."""
    model = Model(load_scene(SCENES / "dbar-rig.toml"))
    fast, ref = Stepper(model, max_dt=5e-3, fast=True), Stepper(model, max_dt=5e-3)
    for _ in range(120):  # 0.6 s: into the braking, the structure turning
        fast.step(0.005)
        ref.step(0.005)
    assert np.abs(model.nodes(fast.x)[0] - model.nodes(ref.x)[0]).max() < 1e-12
    assert np.abs(model.nodes(ref.x)[0][2]).max() > 1e-4  # it has turned


def test_fast_rig_needs_the_option():
    d = read_toml(SCENES / "dbar-rig.toml", SceneError)
    del d["rig_fidelity"]
    with pytest.raises(ValueError, match="rig-fidelity"):
        FastRig(Model(scene_from_dict(d, "no option")))
