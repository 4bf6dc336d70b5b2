"""A scene's attitude against scipy's rotations of the node set, and its [attitude] errors."""

import copy
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import gyrotensegrity
from gyrotensegrity import BodyFrame, SceneError, attitude_of, load_scene, scene_from_dict
from gyrotensegrity.attitude import angle_between, euler_zyx, quaternion_from_matrix

SCENES = Path(gyrotensegrity.__file__).parent / "scenes"
FRAMED = ["dbar-gyro", "dbar-nospin", "dbar-rig", "prism-gyro", "prism-rig", "prism-string-mass"]
# Round-off of a frame built from node differences of order 0.1 m, composed with a rotation:
# a few 1e-16; the margin covers any BLAS's summation order.
TOL = 1e-12
ROTATIONS = Rotation.from_euler(
    "ZYX",
    [[0.3, -0.2, 0.1], [2.9, 1.2, -3.0], [-1.7, -0.9, 2.2], [0.0, 0.0, np.pi - 1e-9]],
)


def moved(scene, rotation: Rotation, shift=(0.0, 0.0, 0.0)):
    """Scene node positions turned by ``rotation`` (world axes) about the origin, then shifted."""
    return rotation.as_matrix() @ scene.positions + np.asarray(shift, float)[:, None]


def same_quaternion(q, reference_wxyz):
    """``q`` equals the reference up to the sign that every quaternion has."""
    sign = 1.0 if np.dot(q, reference_wxyz) >= 0.0 else -1.0
    np.testing.assert_allclose(q, sign * reference_wxyz, atol=TOL)


@pytest.mark.parametrize("name", FRAMED)
def test_shipped_scenes_name_a_frame_that_starts_at_rest(name):
    scene = load_scene(SCENES / f"{name}.toml")
    att = attitude_of(scene, scene.positions)
    np.testing.assert_allclose(att.rotation, np.eye(3), atol=TOL)
    np.testing.assert_allclose(att.quaternion, [1.0, 0.0, 0.0, 0.0], atol=TOL)
    np.testing.assert_allclose(att.rpy_rad, 0.0, atol=TOL)


@pytest.mark.parametrize("name", ["dbar-gyro", "prism-gyro"])
@pytest.mark.parametrize("k", range(len(ROTATIONS)))
def test_a_turned_and_shifted_node_set_against_scipy(name, k):
    """A world rotation Q of the nodes is the attitude F0^T Q F0 in the start frame's axes."""
    scene = load_scene(SCENES / f"{name}.toml")
    frame = BodyFrame(scene)
    att = frame.attitude(moved(scene, ROTATIONS[k], shift=(0.4, -2.0, 7.5)))
    expected = Rotation.from_matrix(frame.F0.T @ ROTATIONS[k].as_matrix() @ frame.F0)
    np.testing.assert_allclose(att.rotation, expected.as_matrix(), atol=TOL)
    same_quaternion(att.quaternion, expected.as_quat(scalar_first=True))
    assert att.quaternion[0] >= 0.0
    np.testing.assert_allclose(att.rpy_rad, expected.as_euler("ZYX")[::-1], atol=1e-9)


def test_angles_are_about_the_start_frames_axes():
    """The prism's frame starts turned from the world's (x along its bottom edge b3 -> b2): a
    turn about its own start y axis is pure pitch."""
    scene = load_scene(SCENES / "prism-rig.toml")
    frame = BodyFrame(scene)
    assert not np.allclose(frame.F0, np.eye(3))
    turn = Rotation.from_rotvec(0.6 * frame.F0[:, 1])
    np.testing.assert_allclose(frame.attitude(moved(scene, turn)).rpy_rad, [0, 0.6, 0], atol=TOL)


def test_translation_and_other_nodes_leave_it_unchanged():
    scene = load_scene(SCENES / "prism-gyro.toml")
    N = moved(scene, ROTATIONS[1])
    reference = attitude_of(scene, N).quaternion
    shifted = N + np.array([[3.0], [-1.0], [0.5]])
    shifted[:, scene.node_index("t1")] += [0.01, 0.02, -0.03]  # no frame node
    np.testing.assert_allclose(attitude_of(scene, shifted).quaternion, reference, atol=TOL)


def test_a_models_node_matrix_gives_the_same_as_the_scenes_positions():
    """The model orders its nodes by bars and adds virtual ones (here: a, b, b, c against the
    scene's c, b, a); :meth:`BodyFrame.of_model` finds the frame's nodes there."""
    data = copy.deepcopy(GOOD)
    data["nodes"] = dict(reversed(list(data["nodes"].items())))
    model = gyrotensegrity.Model(scene_from_dict(data))
    assert model.scene.node_names == ["c", "b", "a"] and model.structure.N0.shape[1] == 4
    turn = ROTATIONS[2].as_matrix()
    expected = attitude_of(model.scene, turn @ model.scene.positions).quaternion
    measured = BodyFrame.of_model(model).attitude(turn @ model.structure.N0).quaternion
    np.testing.assert_allclose(measured, expected, atol=TOL)
    assert not np.allclose(expected, [1, 0, 0, 0])


def test_a_batch_gives_each_its_own():
    scene = load_scene(SCENES / "dbar-gyro.toml")
    N = np.stack([moved(scene, ROTATIONS[k]) for k in range(len(ROTATIONS))])
    att = attitude_of(scene, N)
    assert att.quaternion.shape == (len(ROTATIONS), 4) and att.rpy_rad.shape == (len(ROTATIONS), 3)
    for k in range(len(ROTATIONS)):
        np.testing.assert_allclose(att.quaternion[k], attitude_of(scene, N[k]).quaternion)


@pytest.mark.parametrize("pitch", [np.pi / 2, -np.pi / 2, np.pi / 2 - 1e-12, -np.pi / 2 + 1e-7])
def test_gimbal_lock_neighbourhood_gives_finite_angles_of_the_same_rotation(pitch):
    """At pitch +-90 degrees roll and yaw share an axis: the angles stay finite and still
    compose to the rotation (to the lock threshold's 1e-9 rad)."""
    R = Rotation.from_euler("ZYX", [0.8, pitch, -0.5]).as_matrix()
    rpy = euler_zyx(R)
    assert np.all(np.isfinite(rpy))
    again = Rotation.from_euler("ZYX", rpy[::-1]).as_matrix()
    np.testing.assert_allclose(again, R, atol=1e-8)
    assert rpy[1] == pytest.approx(pitch, abs=1e-7)


@pytest.mark.parametrize("axis", [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, -2, 0.5]])
def test_half_turns_give_the_quaternion_of_scipy(axis):
    """w = 0: the component chosen to divide by is a vector one, never the vanishing w."""
    turn = Rotation.from_rotvec(np.pi * np.asarray(axis, float) / np.linalg.norm(axis))
    q = quaternion_from_matrix(turn.as_matrix())
    same_quaternion(q, turn.as_quat(scalar_first=True))
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=TOL)


def test_angle_between_is_scipys_relative_rotation_at_every_scale():
    """From 1e-9 rad (where 2 acos would give about 1e-8 of round-off) to a half turn, either
    sign of either quaternion."""
    base = ROTATIONS[1]
    for angle in (1e-9, 1e-4, 0.3, 2.0, np.pi):
        other = Rotation.from_rotvec(angle * np.array([0.6, -0.8, 0.0])) * base
        a, b = base.as_quat(scalar_first=True), other.as_quat(scalar_first=True)
        for sign in (1.0, -1.0):
            assert angle_between(a, sign * b) == pytest.approx(angle, rel=1e-5)
    batch = np.stack([a, b])
    np.testing.assert_allclose(angle_between(batch, batch[::-1]), [np.pi, np.pi], rtol=1e-6)


# --- [attitude] in a scene file --------------------------------------------------------------
GOOD = {
    "scene": {"name": "t"},
    "nodes": {"a": [0.0, 0.0, 0.0], "b": [1.0, 0.0, 0.0], "c": [0.0, 1.0, 0.0]},
    "bars": [{"nodes": ["a", "b"], "mass": 1.0}, {"nodes": ["b", "c"], "mass": 1.0}],
    "attitude": {"frame": ["a", "b", "a", "c"]},
}


def with_frame(frame=None, nodes=None, table=None):
    data = copy.deepcopy(GOOD)
    data["constraints"] = {"fixed": [n for n in nodes or {} if n not in GOOD["nodes"]]}
    if frame is not None:
        data["attitude"]["frame"] = frame
    if nodes is not None:
        data["nodes"].update(nodes)
    if table is not None:
        data["attitude"] = table
    return data


def test_the_frame_is_kept_and_written_back():
    scene = scene_from_dict(GOOD, "good.toml")
    assert scene.attitude_frame == ("a", "b", "a", "c")
    assert scene.to_dict()["attitude"] == {"frame": ["a", "b", "a", "c"]}
    del_attitude = {k: v for k, v in GOOD.items() if k != "attitude"}
    assert scene_from_dict(del_attitude).attitude_frame is None


def test_a_scene_without_a_frame_has_no_body_frame():
    scene = scene_from_dict({k: v for k, v in GOOD.items() if k != "attitude"}, "bare.toml")
    with pytest.raises(SceneError, match=r"^bare.toml: attitude: no \[attitude\] table"):
        BodyFrame(scene)


@pytest.mark.parametrize(
    ("data", "key", "what"),
    [
        (with_frame(frame=["a", "b", "a", "z"]), "attitude.frame[3]", "unknown node 'z'"),
        (with_frame(frame=["a", "b", "c"]), "attitude.frame", "list of 4 node names"),
        (with_frame(frame="a b a c"), "attitude.frame", "list of 4 node names"),
        (with_frame(frame=["a", "a", "a", "c"]), "attitude.frame", "x pair's nodes a and a"),
        (with_frame(frame=["a", "b", "c", "c"]), "attitude.frame", "y pair's nodes c and c"),
        (
            with_frame(frame=["a", "d", "a", "c"], nodes={"d": [0.0, 0.0, 0.0]}),
            "attitude.frame",
            "x pair's nodes a and d coincide",
        ),
        (
            with_frame(nodes={"c": [-2.0, 1e-8, 0.0]}),
            "attitude.frame",
            "pairs a-b and a-c are parallel",
        ),
        (with_frame(table={"frame": ["a", "b", "a", "c"], "up": "z"}), "attitude.up", "unknown"),
        (with_frame(table={}), "attitude.frame", "missing"),
    ],
)
def test_bad_frames_name_the_file_and_key(data, key, what):
    with pytest.raises(SceneError) as info:
        scene_from_dict(data, "bad.toml")
    message = str(info.value)
    assert message.startswith(f"bad.toml: {key}: "), message
    assert what in message
