"""The start-state check: a second run against a rig left where the first one ended is refused
before anything moves; the rig's reset makes the next run pass; the comparison itself."""

from dataclasses import replace

import numpy as np
import pytest

from gyrohost.config import StartCheckConfig, load_rig_config
from gyrohost.control.schedule import Schedule
from gyrohost.resources import shipped
from gyrohost.run import RunLoop, RunSettings, with_ports
from gyrohost.run.log import read_stream
from gyrohost.run.start_check import StartState, differences
from gyrohost.simrig.process import RigProcess

CONFIG = load_rig_config(shipped("config", "sim-rig"))
L0 = 0.43105229381822  # both D-bar strings at rest, m
SHORT = RunSettings(lead_in_s=0.2, settle_s=0.2)


def run_on(rig, folder):
    schedule = Schedule(("s13", "s24"), [0.0, 1.0], [[L0, L0], [L0 - 0.05, L0]], "short")
    return RunLoop(with_ports(CONFIG, rig.paths), schedule, folder, settings=SHORT, rig=rig).run()


def test_a_second_run_on_a_moved_rig_is_refused_until_the_rig_is_reset(tmp_path):
    with RigProcess(CONFIG, period_s=0.01) as rig:
        first = run_on(rig, tmp_path / "first")
        assert first.exit_status == 0, first.reason
        second = run_on(rig, tmp_path / "second")
        # s13 stayed 5 cm short where the first run left it
        assert second.exit_status == 2 and not second.completed
        assert second.reason.startswith("start state refused: the rig is not in the scene's")
        assert "servo 's13' string length 0.3811 m, the scene starts at 0.4311 m" in second.reason
        assert "(off by -0.0500 m; tolerance 0.005 m)" in second.reason
        events = read_stream(tmp_path / "second", "events")
        phases = [m for k, m in zip(events["kind"], events["message"], strict=True) if k == "phase"]
        assert phases == ["connect"]  # no hold, no spin-up
        cmd = read_stream(tmp_path / "second", "command")
        assert np.all(cmd["omega_cmd_0_rad_s"] == 0.0)  # the wheels were never commanded
        truth = read_stream(tmp_path / "second", "truth")
        assert np.ptp(truth["s13_rest_m"]) < 1e-6  # nor the servos
        assert rig.command("reset").startswith("reset: truth at the scene's initial state")
        third = run_on(rig, tmp_path / "third")
        assert third.exit_status == 0, third.reason
        events = read_stream(tmp_path / "third", "events")
        checks = [
            m for k, m in zip(events["kind"], events["message"], strict=True) if k == "start_check"
        ]
        assert checks == ["within tolerances"]


AT_REST = StartState(np.zeros(2), np.zeros(3), {"s13": L0, "s24": L0}, np.zeros(4))
TOL = StartCheckConfig()


def test_the_rig_where_the_scene_starts_passes():
    near = StartState(
        np.array([0.05, -0.05]),
        np.array([0.01, -0.02, 0.03]),
        {"s13": L0 + 0.004, "s24": L0 - 0.004},
        np.array([0.9, -0.9, 0, 0]),
    )
    assert differences(AT_REST, near, TOL) == ([], [])


def test_every_difference_is_named_with_how_far_off_it_is():
    # the end of a first run: plane flipped, turning at 1.6 rad/s, s13 short, a wheel coasting
    moved = StartState(
        np.array([3.0, 0.1]),
        np.array([0.0, 1.6, 0.0]),
        {"s13": 0.144, "s24": L0},
        np.array([0.0, 2.5, 0.0, 0.0]),
    )
    found, skipped = differences(AT_REST, moved, TOL)
    assert skipped == [] and len(found) == 4
    assert (
        found[0].startswith("IMU attitude off by 2.968 rad (roll +3.000, pitch +0.100")
        and "tolerance 0.1 rad" in found[0]
    )
    assert found[1].startswith("IMU rate off by 1.600 rad/s")
    assert found[2] == (
        "servo 's13' string length 0.1440 m, the scene starts at 0.4311 m (off by -0.2871 m; "
        "tolerance 0.005 m)"
    )
    assert found[3] == "wheel 1 turning at +2.50 rad/s, not at rest (tolerance 1 rad/s)"
    # yaw is not compared; roll across +-pi is a small angle, not 2 pi
    found, _ = differences(
        replace(AT_REST, roll_pitch_rad=np.array([np.pi - 0.01, 0.0])),
        replace(AT_REST, roll_pitch_rad=np.array([-np.pi + 0.01, 0.0])),
        TOL,
    )
    assert found == []


def test_a_scene_that_starts_turning_is_not_compared_in_attitude():
    tumbling = replace(AT_REST, omega_rad_s=np.array([0.8, 0.0, 0.3]))
    later = replace(AT_REST, roll_pitch_rad=np.array([1.0, 0.5]), omega_rad_s=np.zeros(3))
    found, skipped = differences(tumbling, later, TOL)
    assert found == [] and skipped == [
        "IMU attitude and rate not compared: the scene starts turning at 0.854 rad/s"
    ]
    strict = replace(TOL, length_m=0.001)
    found, _ = differences(
        tumbling, replace(later, lengths_m={"s13": L0 + 0.002, "s24": L0}), strict
    )
    assert len(found) == 1 and found[0].startswith("servo 's13'")


@pytest.mark.parametrize("key", ["attitude_rad", "rate_rad_s", "length_m", "wheel_speed_rad_s"])
def test_each_tolerance_is_the_configured_one(key):
    off = {
        "attitude_rad": replace(AT_REST, roll_pitch_rad=np.array([0.02, 0.0])),
        "rate_rad_s": replace(AT_REST, omega_rad_s=np.array([0.02, 0.0, 0.0])),
        "length_m": replace(AT_REST, lengths_m={"s13": L0 + 0.02, "s24": L0}),
        "wheel_speed_rad_s": replace(AT_REST, wheels_rad_s=np.array([0.02, 0, 0, 0])),
    }[key]
    assert differences(AT_REST, off, replace(TOL, **{key: 0.03}))[0] == []
    assert len(differences(AT_REST, off, replace(TOL, **{key: 0.01}))[0]) == 1
