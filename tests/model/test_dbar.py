"""The paper's D-bar maneuver (Section VI): out-of-plane motion with and without spin."""

from pathlib import Path

import numpy as np
import pytest

import gyrotensegrity
from gyrotensegrity import Model, load_scene, scene_from_dict, simulate

SCENES = Path(gyrotensegrity.__file__).parent / "scenes"


def z_of(run, name):
    names = list(run["node_names"])
    return run["N"][:, 2, names.index(name)]


@pytest.fixture(scope="module")
def gyro_run():
    return simulate(Model(load_scene(SCENES / "dbar-gyro.toml")))


def test_nospin_stays_planar():
    model = Model(load_scene(SCENES / "dbar-nospin.toml"))
    assert "gyroscopic" in model.terms  # wheels at rest can still be spun by their inputs
    run = simulate(model)
    assert np.abs(run["N"][:, 2, :]).max() <= 1e-12
    d13 = np.linalg.norm(run["N"][-1, :, 2] - run["N"][-1, :, 0])
    assert d13 == pytest.approx(0.1437, abs=0.01)  # the string did its work


def test_gyro_tilts_about_n2_n4_axis(gyro_run):
    z1, z3 = z_of(gyro_run, "n1"), z_of(gyro_run, "n3")
    assert 0.01 <= np.abs(z1).max() <= 0.1  # centimetres, as the paper reports
    np.testing.assert_allclose(z3, -z1, atol=1e-9)  # a tilt about y: n1 and n3 opposite
    assert np.abs(z_of(gyro_run, "n2")).max() <= 1e-9


def test_bar_length_error_accurate_settings(gyro_run):
    assert np.abs(gyro_run["bar_length_error"]).max() <= 1e-12
    assert np.abs(gyro_run["joint_error"]).max() <= 1e-12


def test_reversed_spins_reverse_the_tilt(gyro_run):
    import tomllib

    data = tomllib.loads((SCENES / "dbar-gyro.toml").read_text())
    for bar in data["bars"]:
        bar["wheel"]["spin"] = -bar["wheel"]["spin"]
    run = simulate(Model(scene_from_dict(data, "reversed")), duration=1.5)
    k = len(run["t"])
    np.testing.assert_allclose(z_of(run, "n1"), -z_of(gyro_run, "n1")[:k], atol=1e-9)
