"""The maneuver as the run loop plays it: per-servo length ranges, open and closed loop, and the
re-planning worker thread (same plans as on the loop thread, taken at a later tick)."""

import numpy as np
import pytest

from gyrohost.config import load_rig_config
from gyrohost.control import Limits, PlanError, Planner
from gyrohost.control.maneuver import Maneuver, Target
from gyrohost.resources import shipped

SERVOS = load_rig_config(shipped("config", "sim-rig")).servos.servo


def test_each_servo_keeps_its_own_range(dbar):
    per = Limits.per_string(SERVOS)
    assert per.range_of("s13") == (0.12, 0.45) and per.range_of("s24") == (0.40, 0.62)
    # sim-rig: the tightest common range [0.40, 0.45] leaves 0.411..0.45 m of n1-n3 length
    tight = Planner(dbar, Limits.from_servos(SERVOS))
    assert tight.d_hi - tight.d_lo < 0.04
    m = Maneuver(dbar, per, Target(-0.3, 4.0))
    assert m.first.success and m.first.predicted_tilt_rad == pytest.approx(-0.3, abs=1e-3)
    assert not m.schedule.problems(per)
    lo, hi = m.schedule.rest_length.min(axis=0), m.schedule.rest_length.max(axis=0)
    assert lo[0] < 0.40 and hi[1] > 0.45  # uses the room each servo has
    with pytest.raises(PlanError, match="rest shape"):  # s24's range without the square
        Planner(dbar, Limits(string_ranges_m=(("s24", 0.44, 0.62),)))


def drive(maneuver, dbar, steps=120, dt=0.01, join=False):
    """Feed the initial state as the estimate at the loop rate; the schedules played."""
    x = dbar.initial_state()
    played = []
    for k in range(steps):
        played.append(maneuver.update(k * dt, x))
        if join:
            maneuver.join()
    maneuver.join()
    return played


def test_open_loop_plays_the_first_plan_and_closed_loop_replans_at_its_period(dbar):
    limits = Limits.per_string(SERVOS)
    open_ = Maneuver(dbar, limits, Target(-0.3, 4.0))
    assert all(s is open_.first.schedule for s in drive(open_, dbar))
    closed = Maneuver(dbar, limits, Target(-0.3, 4.0, closed_loop=True, adapt=False))
    drive(closed, dbar)
    t = [r.t_s for r in closed.records]
    assert t[0] == 0.0 and np.allclose(np.diff(t[1:]), 0.25) and len(t) == 5  # 0.25..1.0 s
    assert closed.summary()["replans"] == 4 and closed.taken == 4


def test_the_worker_thread_makes_the_same_plans_and_hands_them_over_later(dbar):
    limits = Limits.per_string(SERVOS)
    inline = Maneuver(dbar, limits, Target(-0.3, 4.0, closed_loop=True))
    threaded = Maneuver(dbar, limits, Target(-0.3, 4.0, closed_loop=True, threaded=True))
    drive(inline, dbar)
    played = drive(threaded, dbar, join=True)  # joined: each plan is ready at the next tick
    a, b = inline.records, threaded.records
    assert [r.t_s for r in a] == [r.t_s for r in b]
    assert [r.predicted_tilt_rad for r in a] == pytest.approx([r.predicted_tilt_rad for r in b])
    switches = [k for k in range(1, len(played)) if played[k] is not played[k - 1]]
    assert switches == [26, 51, 76, 101]  # re-planned at ticks 25, 50, ...; taken one tick later
    assert threaded.taken == 4


def test_a_target_out_of_reach_is_refused_with_the_reachable_range(dbar):
    limits = Limits.per_string(SERVOS)
    with pytest.raises(PlanError) as refused:
        Maneuver(dbar, limits, Target(0.2, 4.0))
    message = str(refused.value)
    assert "target tilt +0.2000 rad is out of reach in 4 s" in message
    # s13 can lengthen only to 0.45 m: the plane lands at most 0.084 rad up, far down
    lo, hi = (
        float(v) for v in message.split("lands between ")[1].split(" rad (")[0].split(" and ")
    )
    assert hi == pytest.approx(0.084, abs=1e-3) and lo < -2.0
    best = Maneuver(dbar, limits, Target(hi, 4.0))  # the edge of the range is taken
    assert best.landing_miss_rad < 1e-3
    assert best.summary()["first_plan"]["landing_miss_rad"] == best.landing_miss_rad
    assert Maneuver(dbar, limits, Target(hi, 8.0)).first.success  # a longer maneuver reaches


def test_a_plan_on_the_length_limit_stays_exactly_on_it(dbar):
    limits = Limits.per_string(SERVOS)
    plan = Maneuver(dbar, limits, Target(0.084, 4.0)).first.schedule  # s13 up to 0.45 m
    s13 = plan.rest_length[:, plan.names.index("s13")]
    assert s13.max() == 0.45  # not 0.45000000000000007 (one ulp past, refused by the servo)
    for name, column in zip(plan.names, plan.rest_length.T, strict=True):
        low, high = limits.range_of(name)
        assert low <= column.min() and column.max() <= high


def test_an_attitude_moves_the_strings_it_names():
    """A scene that schedules no string (the prism) moves those the target names."""
    from gyrohost.control.maneuver import planner_for
    from gyrotensegrity import Model, load_scene

    prism = Model(load_scene(shipped("scene", "prism-rig")))
    target = Target(attitude_rpy_rad=(0.01, 0.0, 0.0), strings=("s7", "s8"))
    assert planner_for(prism, Limits(), target).model.names == ("s7", "s8")
    with pytest.raises(PlanError, match="strings to move go with an attitude"):
        Target(tilt_rad=0.1, strings=("s13",))


def test_no_momentum_gain_is_fitted_while_a_planned_wheel_reaction_is_lost():
    """The fit takes the total momentum as kept; a lost reaction's spin-up changes it (the
    prism's wheels meet only strings), so there the re-plans take each estimate's momentum."""
    from gyrohost.control.adapt import MomentumGainFit
    from gyrohost.control.goals import AttitudeGoal
    from gyrohost.control.maneuver import planner_for
    from gyrotensegrity import Model, load_scene

    prism = Model(load_scene(shipped("scene", "prism-rig")))
    x0 = prism.initial_state()
    for mode, fitted in (("both", False), ("wheels", False), ("strings", True)):
        target = Target(attitude_rpy_rad=(0.01, 0.0, 0.0), strings=("s7", "s8"), mode=mode)
        goal = AttitudeGoal(planner_for(prism, Limits(), target), target.attitude_rpy_rad)
        assert isinstance(goal.gain_fit(0.0, x0), MomentumGainFit) == fitted
