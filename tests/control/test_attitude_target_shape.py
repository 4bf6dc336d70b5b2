"""A target shape in the closed loop: the first plan and every re-plan land at its rest lengths."""

import numpy as np
import pytest

from gyrohost.control import Limits, PlanError
from gyrohost.control.maneuver import Maneuver, Target

TARGET_RPY = tuple(np.radians([0.0, -5.0, 0.0]))
SHAPE = {"s13": 0.40}  # 31 mm shorter than at the start; s24 follows the rhombus


@pytest.mark.parametrize(
    "kwargs",
    [
        {"tilt_rad": -0.3, "target_rest": SHAPE},
        {"attitude_rpy_rad": TARGET_RPY, "mode": "wheels", "target_rest": SHAPE},
    ],
)
def test_a_target_shape_needs_an_attitude_whose_strings_move(kwargs):
    with pytest.raises(PlanError, match="a target shape needs an attitude target"):
        Target(**kwargs)


def test_a_string_the_plan_does_not_move_is_refused_before_any_plan(dbar):
    target = Target(attitude_rpy_rad=TARGET_RPY, target_rest={"s99": 0.4})
    with pytest.raises(PlanError, match="s99 not actuated"):
        Maneuver(dbar, Limits(), target)


def test_every_replan_lands_at_the_target_shape(dbar):
    """Re-planned at 4 Hz from a state that does not turn (the plan then has work left at every
    re-plan): the landing rest length is an equality of each programme, so the first plan and
    every accepted re-plan end at 0.40 m to the solver's feasibility (1e-6 m, far below a servo
    step's 0.1 mm), and each plays continuously from the schedule before it."""
    target = Target(attitude_rpy_rad=TARGET_RPY, closed_loop=True, target_rest=SHAPE)
    maneuver = Maneuver(dbar, Limits(), target)
    assert maneuver.schedule.rest_length[-1, 0] == pytest.approx(0.40, abs=1e-6)
    x = dbar.initial_state()
    ends = []
    for k in range(60):
        before = maneuver.schedule
        maneuver.update(0.01 * k, x)
        if maneuver.schedule is not before:
            ends.append(maneuver.schedule.rest_length[-1, 0])
            np.testing.assert_allclose(
                maneuver.schedule(0.01 * k), before(0.01 * k), atol=1e-4
            )  # the splice tolerance
    assert ends, "no re-plan was accepted"
    np.testing.assert_allclose(ends, 0.40, atol=1e-6)
    assert target.to_dict()["target_rest"] == SHAPE  # logged with the run's meta
