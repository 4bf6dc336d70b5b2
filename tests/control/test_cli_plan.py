"""``gyrotens plan``: a schedule file from a target attitude; bad input and unreachable targets
exit 2 with the reason, nothing written."""

import re

import pytest

from gyrohost.cli import main
from gyrohost.control import load_schedule


def test_a_wheels_only_plan_is_written_and_reported(tmp_path, capsys):
    out = tmp_path / "tilt.toml"
    argv = ["plan", "dbar-gyro", "--target-attitude", "0,5,0", "--wheels-only", "-o", str(out)]
    assert main(argv) == 0
    schedule = load_schedule(out)
    assert schedule.names == () and schedule.wheels == ("b12", "b23", "b34", "b41")
    assert schedule.t[-1] == pytest.approx(4.0)
    report = capsys.readouterr().out
    assert re.search(r"lands at roll, pitch, yaw [+-]0\.00, \+5\.00, [+-]0\.00 deg", report)
    assert "peak wheel speed b12" in report


def test_the_prisms_wheels_alone_are_refused_with_an_empty_range(tmp_path, capsys):
    """Its bars meet only strings: a wheel's reaction leaves the prism, so at a held shape
    the wheels turn it by nothing (docs/attitude-plans.md)."""
    out = tmp_path / "roll.toml"
    argv = ["plan", "prism-rig", "--target-attitude", "5,0,0", "--wheels-only", "-o", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "out of reach" in err and "between +0.00 and +0.00 deg" in err, err
    assert not out.exists()


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--target-attitude", "5,0"], "need three numbers"),
        (["--target-attitude", "5,nan,0"], "need three numbers"),
        (["--target-attitude", "0,-20,0", "--strings-only"], "out of reach"),
        (["--target-attitude", "0,0,5", "--strings", "s99"], "no string s99"),
        (["--target-attitude", "0,0,5", "--duration", "-1"], "duration must be positive"),
        (
            ["--target-attitude", "0,0,5", "--max-speed", "0"],
            "--max-speed 0.0: must be a positive number",
        ),
    ],
)
def test_bad_input_exits_2_before_writing(tmp_path, capsys, extra, message):
    out = tmp_path / "plan.toml"
    assert main(["plan", "dbar-gyro", *extra, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("gyrotens plan: error: ") and message in err, err
    assert not out.exists()


def test_a_target_shape_is_where_the_plan_lands(tmp_path, capsys):
    """The D-bar pitched by 5 deg and left with n1-n3 at 0.40 m (31 mm shorter than at the
    start; n2-n4 follows the rhombus): its wheels' momentum then sits elsewhere in the body, so
    the wheels move too."""
    shape, out = tmp_path / "shape.toml", tmp_path / "plan.toml"
    shape.write_text("[rest_length]\ns13 = 0.40\n")
    argv = ["plan", "dbar-gyro", "--target-attitude", "0,-5,0", "--target-shape", str(shape)]
    assert main([*argv, "-o", str(out)]) == 0
    schedule = load_schedule(out)
    assert schedule.names == ("s13", "s24")
    assert schedule.rest_length[-1, 0] == pytest.approx(0.40, abs=1e-6)  # a servo step is mm
    assert schedule.rest_length[0, 0] == pytest.approx(0.43105229381822, abs=1e-9)
    assert "lands at roll, pitch, yaw" in capsys.readouterr().out


@pytest.mark.parametrize(
    "text, message",
    [
        (None, "cannot read"),
        ("rest_length = 3\n", "needs a [rest_length] table"),
        ("[rest_length]\ns13 = -0.4\n", "rest_length.s13 = -0.4: must be a positive number"),
        ("[rest_length]\ns13 = 0.4\n[other]\n", "unknown key(s) other"),
        ("[rest_length]\ns99 = 0.4\n", "s99 not actuated"),
        ("[rest_length]\ns13 = 0.9\n", "s13 = 0.9000 m is outside"),
        ("[rest_length]\ns13 = 0.40\ns24 = 0.40\n", "s24 = 0.4000 m, but the shape its leader"),
    ],
)
def test_a_bad_target_shape_exits_2_naming_it(tmp_path, capsys, text, message):
    shape, out = tmp_path / "shape.toml", tmp_path / "plan.toml"
    if text is not None:
        shape.write_text(text)
    argv = ["plan", "dbar-gyro", "--target-attitude", "0,-5,0", "--target-shape", str(shape)]
    assert main([*argv, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err, err
    assert not out.exists()
