"""Configuration overlays (``gyrotens run --overlay``, what ``gyrotens identify`` writes): merged
key by key into the configuration, ``[[servos.servo]]`` entries by name; errors name the
overlay file and key."""

import math

import pytest

from gyrohost.cli import main
from gyrohost.config import ConfigError, load_rig_config
from gyrohost.resources import shipped

SIM_RIG = shipped("config", "sim-rig")
OVERLAY = """# as gyrotens identify writes it
[imu]
mounting_rpy_rad = [0.0523, -0.0297, 0.0192]

[[servos.servo]]
name = "s24"
length_at_zero_m = 0.4321
"""


def test_an_overlay_sets_its_keys_and_leaves_the_rest(tmp_path):
    overlay = tmp_path / "ident-config.toml"
    overlay.write_text(OVERLAY)
    base, merged = load_rig_config(SIM_RIG), load_rig_config(SIM_RIG, [overlay])
    assert merged.imu.mounting_rpy_rad == (0.0523, -0.0297, 0.0192)
    assert merged.imu.port == base.imu.port and merged.imu.rate_hz == base.imu.rate_hz
    s13, s24 = merged.servos.servo
    assert s13 == base.servos.servo[0]  # untouched: the overlay named only s24
    assert math.isclose(s24.length_at_zero_m, 0.4321) and s24.id == base.servos.servo[1].id
    assert merged.scene_path == base.scene_path  # relative paths stay the configuration's


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            '[[servos.servo]]\nname = "s99"\nid = 3\n',
            r"o\.toml: key 'servos\.servo\[0\]\.name': 's99'",
        ),
        ("imu = 3\n", r"o\.toml: key 'imu': a table against a value"),
        ("[imu]\nrate_hz = 7\n", r"imu\.rate_hz' is 7.*with the overlay .*o\.toml merged"),
    ],
)
def test_overlay_errors_name_the_overlay_and_the_key(tmp_path, text, message):
    overlay = tmp_path / "o.toml"
    overlay.write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_rig_config(SIM_RIG, [overlay])


def test_run_refuses_a_bad_overlay_before_anything_moves(tmp_path, capsys):
    overlay = tmp_path / "o.toml"
    overlay.write_text('[[servos.servo]]\nname = "s99"\n')
    out = tmp_path / "log"
    assert main(["run", "--sim", "--overlay", str(overlay), "-o", str(out)]) == 2
    assert "'s99' names no entry" in capsys.readouterr().err and not out.exists()
