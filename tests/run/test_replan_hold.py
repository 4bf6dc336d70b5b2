"""A closed loop re-plans only from an estimate the IMU still corrects; a hold that lasts a
re-planning period is told once, and its end logged."""

import pytest

from gyrohost.estimator.ekf import Status
from gyrohost.run.replan_hold import ReplanHold, followable

PERIOD_S = 0.25
OK = Status(0)


def test_an_estimate_is_followable_unless_its_imu_is_rejected_or_it_only_predicts():
    assert followable(OK)
    assert followable(Status.WHEELS_REJECTED | Status.SERVOS_TIMEOUT)  # the IMU still corrects
    for bit in (Status.IMU_RATE_REJECTED, Status.IMU_ACCEL_REJECTED, Status.IMU_ANGLE_REJECTED,
                Status.PREDICTION_ONLY):  # fmt: skip
        assert not followable(bit)


@pytest.fixture
def hold():
    lines = []
    hold = ReplanHold(PERIOD_S, lambda m: lines.append(("notice", m)), lambda *e: lines.append(e))
    hold.lines = lines
    return hold


def test_one_rejected_sample_only_delays_a_replan_and_is_not_told(hold):
    assert hold.follow(1.50, OK)
    assert not hold.follow(1.51, Status.IMU_ANGLE_REJECTED)
    assert hold.follow(1.52, OK)
    assert hold.lines == []


def test_a_hold_of_a_period_is_told_once_and_its_end_logged(hold):
    rejected = Status.IMU_RATE_REJECTED | Status.IMU_ACCEL_REJECTED
    follows = [hold.follow(1.6 + 0.01 * k, rejected) for k in range(40)]
    assert not any(follows)
    assert [kind for kind, _ in hold.lines] == ["notice"]  # once, at 0.25 s held
    assert "re-plans held since t = 1.60 s" in hold.lines[0][1]
    assert hold.follow(2.1, OK)
    assert hold.lines[1] == ("replan", "resumed: held 0.50 s")
    assert hold.follow(2.11, OK) and len(hold.lines) == 2
