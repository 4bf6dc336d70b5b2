"""The three-axis closed loop in simulated time: targets checked, re-plans of bounded work on
the re-planning grid, and a truth with heavier wheels landed nearer closed loop than open loop
within the servo and wheel limits.

Truth: dbar-rig (hinges, stators, the motors' reaction: a wheel's speed change turns the
structure, as the planner's momentum balance says) with dbar-gyro's n2-n4 follower string, as
the planner's model assumes (docs/attitude-plans.md), and every wheel's J3 x 1.05. Planner:
the nominal dbar-gyro. Target (10, -20, -27.27) deg, inside the D-bar's reachable set
``tan(yaw) = tan(roll) / sin(pitch)``, landing at 4 s on strings and wheels.
"""

import numpy as np
import pytest

from gyrohost.control import Limits, PlanError
from gyrohost.control.attitude_planner import target_quaternion
from gyrohost.control.maneuver import Maneuver, Target
from gyrohost.control.sil import run_maneuver_sil, scaled_scene
from gyrohost.resources import shipped
from gyrotensegrity import Model
from gyrotensegrity.attitude import angle_between
from gyrotensegrity.compat import tomllib

# Half a minute of simulated maneuvers on one core: beside the simulated rig's real-time tests
# (tests/conftest.py), whose second core would otherwise idle.
pytestmark = pytest.mark.slow

TARGET_RPY = tuple(np.radians([10.0, -20.0, -27.27]))
J3_FACTOR = 1.05
LIMITS = Limits()


def dbar_rig_truth(wheel_inertia=1.0):
    """dbar-rig with the follower string, its wheels' torques left to the SIL's speed loop."""
    data = tomllib.loads(shipped("scene", "dbar-rig").read_text())
    for bar in data["bars"]:
        bar["wheel"].pop("torque")
    data["strings"].append(dict(data["strings"][0], name="s24", nodes=["n2", "n4"]))
    return Model(scaled_scene(data, "dbar-rig with s24", wheel_inertia=wheel_inertia))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({}, "a tilt or an attitude"),
        ({"tilt_rad": -0.3, "attitude_rpy_rad": (0.0, 0.0, 0.1)}, "a tilt or an attitude"),
        ({"attitude_rpy_rad": (0.0, 0.1)}, "3 finite angles"),
        ({"attitude_rpy_rad": (0.0, np.nan, 0.1)}, "3 finite angles"),
        ({"attitude_rpy_rad": (0.0, 0.0, 0.1), "mode": "legs"}, "mode must be one of"),
        ({"attitude_rpy_rad": (0.0, 0.0, 0.1), "actuator_lag_s": -0.01}, "actuator lag"),
        ({"attitude_rpy_rad": (0.0, 0.0, 0.1), "actuator_lag_s": 0.25}, "actuator lag"),
    ],
)
def test_a_target_is_one_tilt_or_one_attitude(kwargs, message):
    with pytest.raises(PlanError, match=message):
        Target(**kwargs)


def test_the_knots_default_by_the_kind_of_target():
    assert Target(-0.3).knots == 6 and Target(-0.3).to_dict()["knots"] == 6
    assert Target(attitude_rpy_rad=(0.0, 0.0, 0.1)).knots == 8


@pytest.fixture(scope="module")
def sil_runs(dbar):
    truth = dbar_rig_truth(J3_FACTOR)
    runs = {}
    for closed in (False, True):
        target = Target(attitude_rpy_rad=TARGET_RPY, closed_loop=closed)
        maneuver = Maneuver(dbar, LIMITS, target)
        runs[closed] = run_maneuver_sil(truth, maneuver, max_dt_s=2e-3, fast=True)  # the kernel
    return runs


def landing_error(run):
    return angle_between(target_quaternion(TARGET_RPY), run.quaternion[run.landing_index])


def test_closed_loop_lands_nearer_than_open_loop_on_heavier_wheels(sil_runs):
    """Open loop: the wheels' momentum exchange is 5 % larger than planned, and so is the
    part of the 33.7-degree turn it drives: to first order 1.7 degrees off; half of that is
    asserted. Closed loop re-plans every 0.25 s from the truth plus noise (1 mm on the nodes:
    about 0.3 degree of attitude on the 0.43 m diagonals) with the momentum and wheel gain
    fitted over the estimates: what is left is that noise and the model error of the last
    period's turn, well under a quarter of the open loop's error."""
    open_, closed = landing_error(sil_runs[False]), landing_error(sil_runs[True])
    print(f"landing error open loop {np.degrees(open_):.3f} deg, closed {np.degrees(closed):.3f}")
    assert open_ > np.radians(0.5 * 0.05 * 33.7)
    assert closed < 0.25 * open_
    records = sil_runs[True].records
    print(f"fitted wheel gain {records[-1].kappa:.4f}")
    # the momentum fit sees the heavier wheels: its gain nearer the truth's 1.05 than 1
    assert abs(records[-1].kappa - J3_FACTOR) < 0.5 * (J3_FACTOR - 1.0)
    assert len(records) == 16  # the first plan and 15 re-plans at 4 Hz before the landing
    assert np.allclose(np.diff([r.t_s for r in records[1:]]), 0.25, atol=0.011)  # a tick late


ACTUATOR_LAG_S = 0.05
"""The simulated rig's servos and wheels (sim-rig's ``servo_lag_s``, ``wheel_lag_s``)."""


def test_re_plans_that_allow_for_the_actuators_lag_land_near_where_they_aim(dbar):
    """Servos and wheels 50 ms behind their commands (the nominal truth otherwise): a re-plan
    that takes the commands of its estimate's time as reached starts from a shape and spins
    the structure has not got yet, and the turn they still make lands past the target, about
    the body rate (20 deg/s mid-maneuver) times the lag: a degree. Planned from the commands
    the actuators have reached (``actuator_lag_s``), only the lag's transient is left;
    asserted: under half the error of the re-plans that ignore it, and under 0.5 deg."""
    truth = dbar_rig_truth()
    error = {}
    for lag in (0.0, ACTUATOR_LAG_S):
        target = Target(attitude_rpy_rad=TARGET_RPY, closed_loop=True, actuator_lag_s=lag)
        run = run_maneuver_sil(truth, Maneuver(dbar, LIMITS, target), max_dt_s=2e-3,
                               fast=True, actuator_lag_s=ACTUATOR_LAG_S)  # fmt: skip
        error[lag] = landing_error(run)
    print({lag: round(float(np.degrees(e)), 3) for lag, e in error.items()})
    assert error[ACTUATOR_LAG_S] < 0.5 * error[0.0]
    assert error[ACTUATOR_LAG_S] < np.radians(0.5)


def test_the_played_schedules_and_the_truth_keep_the_limits(sil_runs):
    for run in sil_runs.values():
        assert run.schedule.problems(LIMITS) == []
        # the speed loop brings each wheel to its command within a step
        assert np.max(np.abs(run.wheel_speed_rad_s)) <= LIMITS.max_wheel_speed_rad_s
        for name, column in zip(run.schedule.names, run.rest_length_m.T, strict=True):
            low, high = LIMITS.range_of(name)
            assert low <= column.min() and column.max() <= high
        rest = run.schedule(run.schedule.t_end)
        np.testing.assert_allclose(rest, run.schedule(0.0), atol=1e-9)  # back at rest


def test_a_replan_ends_within_its_steps_and_the_splice_is_continuous(dbar):
    """From a state that does not turn (behind the plan), at the period: each re-plan either
    improves the plan in force from there or is dropped; either way the schedule is continuous
    at the re-plan's time (the servos see no jump) and within the limits."""
    maneuver = Maneuver(dbar, LIMITS, Target(attitude_rpy_rad=TARGET_RPY, closed_loop=True))
    x = dbar.initial_state()
    before = {}
    for k in range(80):
        before[k] = maneuver.schedule
        maneuver.update(0.01 * k, x)
    t = [r.t_s for r in maneuver.records]
    assert t == pytest.approx([0.0, 0.25, 0.5, 0.75])
    for k in (25, 50, 75):
        np.testing.assert_allclose(
            maneuver.schedule(0.01 * k), before[k](0.01 * k), atol=1e-4
        )  # the splice tolerance
    assert maneuver.schedule.problems(LIMITS) == []
    assert all("steps taken" in r.message for r in maneuver.records[1:])


def test_a_replan_on_a_prism_starts_from_the_scheduled_wheel_speeds():
    """The prism's wheels' reactions leave it, so its reduced state carries that momentum
    after the wheel speeds: a re-plan's state takes the schedule's speeds into the wheels'
    entries only, and the lost momentum from the estimate (none at the start)."""
    from prism_variants import prism

    from gyrohost.control.attitude_planner import AttitudePlanner
    from gyrohost.control.goals import AttitudeGoal
    from gyrohost.control.schedule import Schedule
    from gyrohost.control.shape_attitude import AttitudeModel

    model = prism(100.0, [150.0, -150.0, 150.0])
    reduced = AttitudeModel(model, ["s7", "s8"])
    assert reduced.n_h == 3
    goal = AttitudeGoal(AttitudePlanner(reduced, knots=4), np.radians([2.0, -2.0, 3.0]))
    speeds = np.array([[150.0, -150.0, 150.0], [140.0, -130.0, 120.0]])
    rest = np.tile(reduced.shape.rest, (2, 1))
    schedule = Schedule(("s7", "s8"), [0.0, 1.0], rest, wheels=reduced.wheels, wheel_speed=speeds)
    x0, _ = goal.state(0.5, model.initial_state(), schedule)
    assert x0.shape == (reduced.size[0],)
    np.testing.assert_array_equal(reduced.split(x0)[2], speeds.mean(axis=0))
    np.testing.assert_array_equal(x0[-3:], 0.0)
