"""Where the wheels are played by their logged or emulated speeds (the identification's forward
model, the in-process SIL), a scene whose wheels act through the motors' reaction is refused
with its key named, before anything runs: its truth's wheels are torque-driven."""

import pytest

from gyrohost.config import load_rig_config
from gyrohost.ident.errors import IdentDataError
from gyrohost.ident.forward import simulate
from gyrohost.resources import shipped
from gyrohost.sil.errors import SilError
from gyrohost.sil.scoring import rig_model_run
from gyrohost.simrig.config import with_truth_scene
from gyrotensegrity import load_scene

CONFIG = load_rig_config(shipped("config", "sim-rig"))
REACTION = '\n[rig_fidelity]\njoints = "ball"\nstator_inertia = 1.2e-5\nmotor_reaction = true\n'


@pytest.fixture
def reaction_scene(tmp_path):
    """dbar-gyro (the same members as sim-rig's scene) with the motors' reaction."""
    path = tmp_path / "dbar-reaction.toml"
    path.write_text(shipped("scene", "dbar-gyro").read_text() + REACTION)
    return path


def test_identification_refuses_a_scene_with_the_motors_reaction(reaction_scene):
    with pytest.raises(IdentDataError, match=r"\[rig_fidelity\] motor_reaction"):
        simulate(load_scene(reaction_scene), CONFIG, rec=None)


def test_the_in_process_sil_refuses_a_truth_with_the_motors_reaction(reaction_scene):
    with pytest.raises(SilError, match=r"\[rig_fidelity\] motor_reaction"):
        rig_model_run(with_truth_scene(CONFIG, reaction_scene), seed=1, duration_s=0.5)
