"""prism-rig with stiffer strings or other wheel spins, for the attitude model's and planner's
tests (a stiffer prism keeps its quasi-static shape: every force density scales alike)."""

from gyrohost.resources import shipped
from gyrotensegrity import Model, scene_from_dict
from gyrotensegrity.compat import tomllib


def prism(stiffness_factor=1.0, spins=None):
    """A model of prism-rig, strings ``stiffness_factor`` times stiffer, wheels at ``spins``
    (rad/s, bar order; default the scene's)."""
    data = tomllib.loads(shipped("scene", "prism-rig").read_text())
    for string in data["strings"]:
        string["stiffness"] *= stiffness_factor
    for bar, spin in zip(data["bars"], spins or [], strict=False):
        bar["wheel"]["spin"] = spin
    return Model(scene_from_dict(data, "prism.toml"))
