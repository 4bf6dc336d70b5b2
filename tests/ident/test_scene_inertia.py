"""Identified inertias in a scene file: ``J3``/``J1`` of a wheel and ``inertia`` of a bar
override the disc's and the uniform bar's formulas, on the reference and the fast path."""

import math
import re

import numpy as np
import pytest

from gyrotensegrity import Model, SceneError, load_scene, simulate

BASE = """
[scene]
name = "{name}"
duration = 0.1
[nodes]
n1 = [-0.2, 0.0, 0.0]
n2 = [0.0, 0.2, 0.0]
n3 = [0.2, 0.0, 0.0]
[velocities]
n2 = [0.0, 0.0, 0.3]
[[bars]]
nodes = ["n1", "n2"]
mass = 0.1
{bar_extra}
wheel = {{ mass = 0.05, radius = 0.031, thickness = 0.012, spin = 70.0{wheel_extra} }}
[[bars]]
nodes = ["n2", "n3"]
mass = 0.1
wheel = {{ mass = 0.05, radius = 0.031, thickness = 0.012, spin = -70.0 }}
[[strings]]
nodes = ["n1", "n3"]
stiffness = 100.0
damping = 1.0
rest_length = 0.3
[simulation]
integrator = "rk4"
dt = 1e-3
"""
J3_DISC = 0.5 * 0.05 * 0.031**2  # the formula's value, the same float the model computes


def _scene(tmp_path, name="s", bar_extra="", wheel_extra=""):
    path = tmp_path / f"{name}.toml"
    path.write_text(BASE.format(name=name, bar_extra=bar_extra, wheel_extra=wheel_extra))
    return load_scene(path)


def _nodes(scene, fast):
    """Node positions and wheel spins of a 0.1 s run, shapes (k, 3, n) and (k, n_w)."""
    run = simulate(Model(scene), fast=fast)
    return np.concatenate([run["N"].ravel(), run["omega_w"].ravel()])


@pytest.mark.parametrize("fast", [False, True])
def test_explicit_j3_equal_to_the_formula_gives_the_identical_run(tmp_path, fast):
    plain = _scene(tmp_path, "plain")
    explicit = _scene(tmp_path, "explicit", wheel_extra=f", J3 = {J3_DISC!r}")
    assert explicit.bars[0].wheel.J3 == J3_DISC
    np.testing.assert_array_equal(_nodes(plain, fast), _nodes(explicit, fast))


@pytest.mark.parametrize("fast", [False, True])
def test_a_different_j3_changes_the_run(tmp_path, fast):
    plain = _nodes(_scene(tmp_path, "plain"), fast)
    heavier = _nodes(_scene(tmp_path, "heavy", wheel_extra=f", J3 = {1.3 * J3_DISC!r}"), fast)
    assert np.max(np.abs(heavier - plain)) > 1e-5


def test_j1_and_bar_inertia_enter_the_transverse_inertia(tmp_path):
    scene = _scene(tmp_path, bar_extra="inertia = 2.0e-3", wheel_extra=", J1 = 4.0e-5, J3 = 5e-5")
    model = Model(scene)
    length = math.hypot(0.2, 0.2)
    assert model.J3[0] == 5e-5 and model.J1[0] == 4.0e-5
    assert model.J_t[0] == pytest.approx((2.0e-3 + 4.0e-5) / length**2, rel=1e-12)
    plain = Model(_scene(tmp_path, "plain"))
    assert model.J_t[1] == plain.J_t[1]  # the other bar keeps its formulas
    assert scene.to_dict()["bars"][0]["inertia"] == 2.0e-3


@pytest.mark.parametrize(
    "extra, key",
    [
        (("", ", J3 = 0.0"), "bars[0].wheel.J3"),
        (("", ", J1 = -1e-5"), "bars[0].wheel.J1"),
        (("", ", J3 = nan"), "bars[0].wheel.J3"),
        (("", ", J3 = 'big'"), "bars[0].wheel.J3"),
        (("inertia = inf", ""), "bars[0].inertia"),
        (("inertia = 0.0", ""), "bars[0].inertia"),
    ],
)
def test_bad_inertias_are_refused_naming_file_and_key(tmp_path, extra, key):
    with pytest.raises(SceneError, match="bad.toml: " + re.escape(key)):
        _scene(tmp_path, "bad", *extra)
