"""Dynamics of gyroscopic tensegrity structures (Goyal, Chen, Majji, Skelton).

Depends on numpy and scipy only. Typical use::

    from gyrotensegrity import Model, load_scene, simulate
    model = Model(load_scene("model/gyrotensegrity/scenes/dbar-gyro.toml"))
    run = simulate(model)            # or Stepper(model).step(dt, u)
    run.save("out/dbar.npz")

See docs/model.md for the equations-to-code map and the API.
"""

__version__ = "0.1.0"

from .attitude import BodyFrame, attitude_of  # noqa: E402
from .dynamics import evaluate, rhs  # noqa: E402
from .errors import PrunedTermError, SceneError, SimulationError  # noqa: E402
from .model import Model  # noqa: E402
from .runfile import Run, load_run  # noqa: E402
from .scene import Scene, load_scene, scene_from_dict  # noqa: E402
from .simulate import Stepper, simulate  # noqa: E402

__all__ = [
    "BodyFrame",
    "Model",
    "PrunedTermError",
    "Run",
    "Scene",
    "SceneError",
    "SimulationError",
    "Stepper",
    "attitude_of",
    "evaluate",
    "load_run",
    "load_scene",
    "rhs",
    "scene_from_dict",
    "simulate",
]
