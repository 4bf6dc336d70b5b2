"""Bad scenes get a SceneError naming the key and what is wrong (one test per error kind)."""

import copy

import pytest

from gyrotensegrity import SceneError, load_scene, scene_from_dict

GOOD = {
    "scene": {"name": "t", "duration": 1.0},
    "nodes": {"a": [0.0, 0.0, 0.0], "b": [1.0, 0.0, 0.0], "c": [0.0, 1.0, 0.0]},
    "bars": [{"nodes": ["a", "b"], "mass": 1.0}, {"nodes": ["b", "c"], "mass": 1.0}],
    "strings": [{"nodes": ["a", "c"], "stiffness": 10.0}],
}


def edited(path, value):
    data = copy.deepcopy(GOOD)
    target = data
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    return data


def test_good_scene_loads():
    scene = scene_from_dict(GOOD, "good.toml")
    assert [b.name for b in scene.bars] == ["b1", "b2"]


@pytest.mark.parametrize(
    ("path", "value", "key", "what"),
    [
        (("bars", 0, "colour"), "red", "bars[0].colour", "unknown key"),
        (("scene", "spin"), 1.0, "scene.spin", "unknown key"),
        (("bars", 1, "nodes"), ["b", "z"], "bars[1].nodes[1]", "unknown node 'z'"),
        (("strings", 0, "nodes"), ["a", "q"], "strings[0].nodes[1]", "unknown node 'q'"),
        (("nodes", "c"), [1.0, 0.0, 0.0], "bars[1].nodes", "zero-length bar"),
        (("bars", 0, "mass"), -1.0, "bars[0].mass", "must be positive"),
        (("bars", 0, "mass"), float("nan"), "bars[0].mass", "must be finite"),
        (("nodes", "a"), [0.0, float("inf"), 0.0], "nodes.a[1]", "must be finite"),
        (
            ("strings", 0, "rest_length"),
            {"t": [0.0, 2.0, 1.0], "value": [1.0, 1.0, 1.0]},
            "strings[0].rest_length.t[2]",
            "must increase strictly",
        ),
        (("strings", 0, "stiffness"), "stiff", "strings[0].stiffness", "must be a number"),
    ],
)
def test_bad_scene_names_key(path, value, key, what):
    with pytest.raises(SceneError) as info:
        scene_from_dict(edited(path, value), "bad.toml")
    message = str(info.value)
    assert message.startswith(f"bad.toml: {key}: "), message
    assert what in message


def test_negative_wheel_mass():
    data = edited(("bars", 0, "wheel"), {"mass": -0.1, "radius": 0.03, "thickness": 0.01})
    with pytest.raises(SceneError, match=r"bars\[0\]\.wheel\.mass: must be positive"):
        scene_from_dict(data, "bad.toml")


def test_massless_string_node():
    data = edited(("nodes", "d"), [2.0, 0.0, 0.0])
    data["strings"].append({"nodes": ["c", "d"], "stiffness": 1.0})
    with pytest.raises(SceneError, match=r"nodes\.d: string-to-string node without mass"):
        scene_from_dict(data, "bad.toml")


def test_toml_syntax_error_names_file(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text("[scene\nname = 1\n")
    with pytest.raises(SceneError, match=r"broken\.toml: invalid TOML"):
        load_scene(path)


def test_missing_file(tmp_path):
    with pytest.raises(SceneError, match=r"nothere\.toml: cannot read"):
        load_scene(tmp_path / "nothere.toml")
