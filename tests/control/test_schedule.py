"""Schedule files, limits and the paper preset."""

import json
import math

import numpy as np
import pytest

from gyrohost.control import Limits, Schedule, ScheduleError, load_schedule, preset
from gyrohost.control.schedule import schedule_from_dict
from gyrohost.resources import shipped_dir
from gyrotensegrity.compat import tomllib

SCENES = shipped_dir("scene")


def simple():
    return Schedule(("s13", "s24"), [0.0, 1.0, 2.0], [[0.4, 0.4], [0.35, 0.45], [0.4, 0.4]], "x")


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_round_trip(tmp_path, suffix):
    s = simple()
    back = load_schedule(s.save(tmp_path / f"a{suffix}"))
    assert back.names == s.names and back.name == "x"
    np.testing.assert_array_equal(back.t, s.t)
    np.testing.assert_array_equal(back.rest_length, s.rest_length)


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_the_purpose_round_trips_and_is_left_out_where_it_is_the_default(tmp_path, suffix):
    s = simple()
    assert s.purpose == "run" and "purpose" not in s.to_dict()["schedule"]
    ident = Schedule(s.names, s.t, s.rest_length, "x", purpose="identification")
    assert load_schedule(ident.save(tmp_path / f"a{suffix}")).purpose == "identification"
    assert ident.splice(s, 1.0).purpose == "identification"
    with pytest.raises(ScheduleError, match="purpose 'record' is none of run, identification"):
        Schedule(s.names, s.t, s.rest_length, "x", purpose="record")


def test_evaluation_is_linear_and_held():
    s = simple()
    np.testing.assert_allclose(s(0.5), [0.375, 0.425])
    np.testing.assert_allclose(s(-1.0), [0.4, 0.4])
    np.testing.assert_allclose(s(9.0), [0.4, 0.4])
    np.testing.assert_allclose(s.max_speeds(), [0.05, 0.05])


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d["schedule"].update(t_s=[0.0, 2.0, 1.0]), r"a\.toml: schedule\.t_s\[2\]"),
        (lambda d: d["rest_length_m"].update(s13=[0.4, 0.3]), r"rest_length_m\.s13: has 2"),
        (lambda d: d["rest_length_m"].update(s13=[0.4, -0.3, 0.4]), r"s13\[1\]: negative"),
        (lambda d: d["rest_length_m"].update(s13=[0.4, "x", 0.4]), r"s13\[1\]: must be"),
        (lambda d: d.update(extra=1), r"extra: unknown key"),
        (lambda d: d.pop("schedule"), r"schedule: missing"),
        (lambda d: d["schedule"].update(purpose="record"), r"schedule\.purpose: must be one"),
    ],
)
def test_errors_name_file_and_key(tmp_path, edit, message):
    data = simple().to_dict()
    edit(data)
    with pytest.raises(ScheduleError, match=message):
        schedule_from_dict(data, "a.toml")


def test_unreadable_and_unparsable_files(tmp_path):
    with pytest.raises(ScheduleError, match="cannot read"):
        load_schedule(tmp_path / "missing.toml")
    bad = tmp_path / "bad.json"
    bad.write_text("{", encoding="utf-8")
    with pytest.raises(ScheduleError, match="bad.json: cannot parse"):
        load_schedule(bad)


def test_limits_problems_and_validation():
    s = simple()
    assert s.problems(Limits(max_speed_m_s=0.05)) == []
    assert "s13: speed" in s.problems(Limits(max_speed_m_s=0.04))[0]
    assert "outside" in s.problems(Limits(max_length_m=0.42))[0]
    with pytest.raises(ScheduleError, match="max_speed_m_s"):
        Limits(max_speed_m_s=0.0)
    with pytest.raises(ScheduleError, match="min_length_m < max_length_m"):
        Limits(min_length_m=0.5, max_length_m=0.4)


def test_the_wheel_limits_are_the_boards_defaults():
    """Limits' wheel speed and acceleration are the wheel board's SPEED_MAX and ACCEL_RAD_S2 as
    its parameter table ships them (gyrotens plan takes them when not given)."""
    from gyrohost.drivers.wheelproto import PARAM_BY_NAME

    assert Limits().max_wheel_speed_rad_s == PARAM_BY_NAME["SPEED_MAX_MRAD_S"].default / 1000
    assert Limits().max_wheel_accel_rad_s2 == PARAM_BY_NAME["ACCEL_RAD_S2"].default


def test_wheel_speeds_and_accelerations_beyond_the_limits_are_problems():
    """The board's SPEED_MAX (157.08 rad/s) and setpoint ramp (100 rad/s^2) by default."""
    s = Schedule((), [0.0, 1.0, 1.5], np.zeros((3, 0)), "w", ("b12",), [[0.0], [90.0], [150.0]])
    assert s.problems(Limits()) == ["wheel b12: 120 rad/s^2 exceeds 100"]
    assert s.problems(Limits(max_wheel_accel_rad_s2=120.0)) == []
    assert s.problems(Limits(max_wheel_speed_rad_s=140.0, max_wheel_accel_rad_s2=200.0)) == [
        "wheel b12: 150 rad/s exceeds 140"
    ]
    with pytest.raises(ScheduleError, match="max_wheel_speed_rad_s"):
        Limits(max_wheel_speed_rad_s=float("nan"))


def test_splice_keeps_the_command_continuous():
    a = simple()
    b = Schedule(a.names, [0.5, 3.0], [a(0.5), [0.3, 0.5]], "b")
    c = a.splice(b, 0.5)
    for t in (0.0, 0.25, 0.5):
        np.testing.assert_allclose(c(t), a(t))
    for t in (0.5, 1.0, 2.0, 4.0):
        np.testing.assert_allclose(c(t), b(t))
    jump = Schedule(a.names, [0.0, 3.0], [[0.3, 0.5], [0.3, 0.5]], "b")
    with pytest.raises(ScheduleError, match="jump"):
        a.splice(jump, 0.5)


def test_a_late_plan_is_joined_by_the_fastest_move_the_limits_allow():
    """A plan taken later than the estimate it was made from departs from the command played:
    the join moves onto it at the servos' and the wheels' largest rates, without a jump."""
    limits = Limits(max_speed_m_s=0.05, max_wheel_accel_rad_s2=100.0)
    a = Schedule(("s13",), [0.0, 2.0], [[0.40], [0.40]], "a", ("b12",), [[50.0], [50.0]])
    t_b = np.arange(0.0, 2.01, 0.05)
    b = Schedule(("s13",), t_b, np.full((t_b.size, 1), 0.39), "b", ("b12",),
                 np.full((t_b.size, 1), 60.0))  # fmt: skip
    c = a.join(b, 0.5, limits)
    np.testing.assert_allclose(c(0.5), [0.40])  # no jump where it is taken
    assert c.problems(limits) == []  # the move keeps the servos' speed and the ramp
    # 10 mm at 0.05 m/s: the first of b's samples 0.2 s on, b from there
    np.testing.assert_allclose(c(0.7), [0.39])
    for t in (0.7, 1.0, 2.0):
        np.testing.assert_allclose(c(t), b(t))
        np.testing.assert_allclose(c.wheel_speeds(t), b.wheel_speeds(t))
    assert c(0.6)[0] > 0.39 + 1e-6  # still on its way at 0.1 s
    short = Schedule(("s13",), [0.5, 0.55], [[0.39], [0.38]], "s", ("b12",), [[60.0], [60.0]])
    end = a.join(short, 0.5, limits)  # ends before it is reached: its last value, as fast
    np.testing.assert_allclose(end.t[-1], 0.5 + 0.02 / 0.05)
    assert end.problems(limits) == []


def test_splice_of_wheel_speeds_alone_and_near_a_sample():
    """A wheels-only schedule has no rest length to jump; a splice a round-off after a sample
    drops that sample instead of a rate over 1e-16 s."""
    none = np.zeros((2, 0))
    a = Schedule((), [0.0, 0.5, 1.0], np.zeros((3, 0)), "a", ("b12",), [[0.0], [25.0], [50.0]])
    b = Schedule((), [0.5, 1.0], none, "b", ("b12",), [[25.0], [0.0]])
    t = float(np.nextafter(0.5, 1.0))
    c = a.splice(b, t)
    assert c.t.tolist() == [0.0, t, 1.0] and c.problems(Limits()) == []
    np.testing.assert_allclose(c.wheel_speeds(0.75), [12.5])


def test_bind_rejects_unknown_strings(dbar):
    s = Schedule(("s99",), [0.0], [[0.4]])
    with pytest.raises(ScheduleError, match="s99 not in scene dbar-gyro"):
        s.input_at(dbar, 0.0)


def test_paper_preset_is_the_scene_maneuver(dbar):
    """Against the scene file's own rest-length tables (written independently)."""
    s = preset("paper", dbar)
    data = tomllib.loads((SCENES / "dbar-gyro.toml").read_text())
    for i, string in enumerate(data["strings"]):
        table = string["rest_length"]
        got = [s.input_at(dbar, t)[i] for t in table["t"]]
        np.testing.assert_allclose(got, table["value"], atol=1e-9)
    # 1/3 in 3 s is faster than the default servo limit of 0.05 m/s
    assert any("s13: speed" in p for p in s.problems(Limits()))
    with pytest.raises(ScheduleError, match="unknown preset"):
        preset("nope", dbar)
    json.dumps(s.to_dict())


def test_shipped_schedules(dbar):
    root = shipped_dir("schedule")
    paper = load_schedule(root / "paper.toml")
    np.testing.assert_allclose(paper.rest_length, preset("paper", dbar).rest_length, atol=1e-12)
    tilt = load_schedule(root / "tilt-0.3rad-4s.toml")
    assert tilt.problems(Limits(max_speed_m_s=0.05)) == []
    tilt.input_at(dbar, 1.0)  # its strings are the scene's
    assert paper.purpose == tilt.purpose == "run"
    assert load_schedule(root / "identify.toml").purpose == "identification"


def test_limits_from_servo_config():
    from gyrohost.config import ServoConfig

    servos = (
        ServoConfig("s13", 1, 0.01, max_speed_m_s=0.05, min_length_m=0.1, max_length_m=0.7),
        ServoConfig("s24", 2, 0.01, max_speed_m_s=0.04, min_length_m=0.05, max_length_m=0.8),
    )
    lim = Limits.from_servos(servos)
    assert (lim.max_speed_m_s, lim.min_length_m, lim.max_length_m) == (0.04, 0.1, 0.7)
    with pytest.raises(ScheduleError, match="no servos"):
        Limits.from_servos(())


def with_wheels():
    """``simple`` with the wheel on b12 stepped from 74.9 to 86.1 rad/s between 1 and 2 s."""
    s = simple()
    return Schedule(s.names, s.t, s.rest_length, "w", ("b12",), [[74.9], [74.9], [86.1]])


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_wheel_speeds_round_trip_and_interpolate(tmp_path, suffix):
    s = with_wheels()
    back = load_schedule(s.save(tmp_path / f"w{suffix}"))
    assert back.wheels == ("b12",)
    np.testing.assert_array_equal(back.wheel_speed, s.wheel_speed)
    np.testing.assert_allclose(back.wheel_speeds(1.5), [80.5])
    np.testing.assert_allclose(back.wheel_speeds(9.0), [86.1])  # held after the last sample
    assert simple().wheels == () and simple().wheel_speeds(1.0).shape == (0,)


def test_a_schedule_of_wheel_speeds_alone_is_a_schedule():
    data = {"schedule": {"t_s": [0.0, 1.0]}, "wheel_speed_rad_s": {"b23": [-74.9, -60.0]}}
    s = schedule_from_dict(data, "w.toml")
    assert s.names == () and s.rest_length.shape == (2, 0) and s.wheels == ("b23",)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d["wheel_speed_rad_s"].update(b12=[1.0, 2.0]), r"w\.toml: wheel_speed_rad_s\.b"),
        (lambda d: d["wheel_speed_rad_s"].update(b12=[1.0, math.nan, 2.0]), r"b12\[1\]: must be"),
        (lambda d: d.update(wheel_speed_rad_s=3.0), r"wheel_speed_rad_s: must be a table"),
    ],
)
def test_wheel_speed_errors_name_file_and_key(edit, message):
    data = with_wheels().to_dict()
    edit(data)
    with pytest.raises(ScheduleError, match=message):
        schedule_from_dict(data, "w.toml")


def test_wheels_bind_to_the_scene_wheels_by_bar(dbar):
    s = with_wheels()
    assert s.bind_wheels(dbar) == [0]
    other = Schedule(s.names, s.t, s.rest_length, "w", ("s13",), s.wheel_speed)
    with pytest.raises(ScheduleError, match="on s13 not in scene .* wheels on b12, b23, b34, b41"):
        other.bind_wheels(dbar)
    # the shipped D-bar's wheels are torque-driven: a speed is no input of that model
    with pytest.raises(ScheduleError, match="b12 are torque-driven"):
        s.input_at(dbar, 0.0)
