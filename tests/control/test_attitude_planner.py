"""Three-axis attitude plans: targets reached on the reduced model within the limits, the
one-axis model's tilt from a strings-only plan, refusals with the reachable range, warm start."""

import re

import numpy as np
import pytest
from prism_variants import prism

from gyrohost.control import Limits, PlanError
from gyrohost.control.attitude_planner import (
    FEASIBLE,
    LANDING_RATE_RAD_S,
    AttitudePlanner,
    AttitudeWeights,
    plan_attitude,
    target_quaternion,
)
from gyrohost.control.reduced import DBarReduced
from gyrohost.control.shape_attitude import AttitudeModel
from gyrohost.resources import shipped
from gyrotensegrity import Model, load_scene

PRISM_TARGET_DEG = (1.0, -1.0, 1.5)
"""A turn of 2.1 deg about an axis off the body's axes and off the momentum: the prism's wheels
turn it only while its shape changes (their reactions leave it), so its reach is degrees."""
PRISM_OPTIONS = dict(knots=4, weights=AttitudeWeights(1e-6, 1e-6))
"""Effort weights far below the landing term's (2.1 deg is 1.3e-3 rad^2; the default 1e-4 on
inputs near their limits weighs as much as a landing 0.6 deg off), so that the effort does not
pull the landing off."""


@pytest.fixture(scope="module")
def stiff_prism():
    return prism(100.0, [150.0, -150.0, 150.0])


@pytest.fixture(scope="module")
def prism_plan(stiff_prism):
    return plan_attitude(
        stiff_prism, np.radians(PRISM_TARGET_DEG), 6.0, strings=["s7", "s8"], **PRISM_OPTIONS
    )


def test_a_prism_reaches_a_three_axis_target_with_strings_and_wheels(prism_plan):
    """Its wheels act only gyroscopically (their reactions leave it): a problem second order in
    the inputs, planned with MAX_ITER_GYROSCOPIC iterations."""
    plan = prism_plan
    assert plan.success, plan.message
    assert plan.landing_error_rad < 0.005
    # kept as the planner keeps its constraints: its square within FEASIBLE (rad^2/s^2)
    assert plan.landing_rate_rad_s**2 <= LANDING_RATE_RAD_S**2 + FEASIBLE
    s = plan.schedule
    assert s.names == ("s7", "s8") and s.wheels == ("bar1", "bar2", "bar3")
    assert s.problems(Limits()) == []
    assert np.ptp(s.wheel_speed, axis=0).min() > 1.0  # every wheel takes part
    np.testing.assert_allclose(s.rest_length[-1], s.rest_length[0], atol=1e-9)  # lands at rest
    assert s.t[0] == 0.0 and s.t[-1] == pytest.approx(6.0)


def test_a_replan_from_the_plan_itself_starts_where_it_ends(stiff_prism, prism_plan):
    """Knots in absolute time: the previous plan is the warm start of a re-plan half way, from
    its own state there: already feasible and near optimal, it converges in fewer evaluations
    than the cold start and still lands within the tolerance."""
    model = AttitudeModel(stiff_prism, ["s7", "s8"])
    planner = AttitudePlanner(model, **PRISM_OPTIONS)
    _, H0 = model.start(stiff_prism.initial_state())
    kt = planner.knot_times(0.0, 6.0)
    again = planner.plan(prism_plan.target_q, kt, kt[2], prism_plan.states[2], H0, prism_plan)
    assert again.success and again.landing_error_rad < 0.005
    assert again.n_eval < prism_plan.n_eval
    assert again.schedule.t[0] == kt[2]


def test_a_strings_only_plan_tilts_the_dbar_as_the_one_axis_model_says():
    """A pitch target with the wheels held: the plan's n1-n3 rest lengths, played through
    DBarReduced (the tilt planner's model, an independent quadrature), land at the target
    (to its linear tabulation and the schedule's sampling: 1e-3 rad)."""
    model = Model(load_scene(shipped("scene", "dbar-gyro")))
    plan = plan_attitude(model, np.radians([0.0, -10.0, 0.0]), 4.0, mode="strings")
    assert plan.schedule.wheels == ()
    dbar = DBarReduced(model)
    t = np.linspace(0.0, 4.0, 4001)
    d = np.interp(t, plan.schedule.t, plan.schedule.rest_length[:, 0])
    H_a = dbar.momentum(model.initial_state(), model.input_at(0.0))
    tilt = dbar.final_tilt(t, d, 0.0, H_a, model.spin0)
    assert tilt == pytest.approx(np.radians(-10.0), abs=1e-3)


def test_an_unreachable_target_is_refused_with_the_range_about_its_axis():
    """The D-bar's strings alone cannot pitch it by -20 deg in 4 s (as the tilt planner's reach
    says too): refused, with the reachable pitch range, which excludes the target."""
    model = Model(load_scene(shipped("scene", "dbar-gyro")))
    with pytest.raises(PlanError, match=r"out of reach .* lands turned between") as error:
        plan_attitude(model, np.radians([0.0, -20.0, 0.0]), 4.0, mode="strings")
    lo, hi = (
        float(v)
        for v in re.search(r"between ([-+.\d]+) and ([-+.\d]+) deg", str(error.value)).groups()
    )
    assert not lo <= 20.0 <= hi  # the turn is +20 deg about the axis -y
    assert lo < 0.0 < hi


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"mode": "fast"}, "mode must be one of"),
        ({"target": [0.0, np.nan, 0.0]}, "three finite angles"),
        ({"duration": 0.0}, "duration must be positive"),
        ({"strings": ["s99"]}, "no string s99"),
    ],
)
def test_bad_requests_are_refused_before_planning(stiff_prism, kwargs, message):
    target = kwargs.pop("target", [0.1, 0.0, 0.0])
    duration = kwargs.pop("duration", 4.0)
    with pytest.raises(PlanError, match=message):
        plan_attitude(stiff_prism, target, duration, **kwargs)


def test_the_target_angles_are_the_frames_zyx_convention():
    from scipy.spatial.transform import Rotation

    from gyrotensegrity.attitude import euler_zyx

    rpy = np.radians([10.0, -20.0, 30.0])
    R = Rotation.from_quat(target_quaternion(rpy), scalar_first=True).as_matrix()
    np.testing.assert_allclose(euler_zyx(R), rpy, atol=1e-12)
