"""A closed loop re-plans only from an estimate the IMU still corrects; otherwise the schedule in
force plays on, and the hold is told once and its end logged."""

from types import SimpleNamespace

import numpy as np
import pytest

from gyrohost.estimator.ekf import Status
from gyrohost.run.sequence import RunLoop, followable

NONE = Status(0)


def test_an_estimate_is_followable_unless_its_imu_is_rejected_or_it_only_predicts():
    assert followable(Status(0))
    assert followable(Status.WHEELS_REJECTED | Status.SERVOS_TIMEOUT)  # the IMU still corrects
    for bit in (Status.IMU_RATE_REJECTED, Status.IMU_ACCEL_REJECTED, Status.IMU_ANGLE_REJECTED,
                Status.PREDICTION_ONLY):  # fmt: skip
        assert not followable(bit)


class Loop(SimpleNamespace):
    """The parts of a RunLoop that following an estimate touches."""

    def __init__(self):
        updates, lines = [], []
        super().__init__(
            estimator=SimpleNamespace(status=Status(0)),
            maneuver=SimpleNamespace(
                update=lambda t, x: updates.append(t) or f"schedule {t:.2f}",
                records=[],
                target=SimpleNamespace(closed_loop=True),
            ),
            replans=SimpleNamespace(write=lambda records: None),
            schedule="first plan",
            t_schedule_s=1.0,
            _replans_held_s=float("nan"),
            updates=updates,
            lines=lines,
            notice=lambda message: lines.append(("notice", message)),
            event=lambda kind, message: lines.append((kind, message)),
        )

    def follow(self, t_s, status=NONE):
        self.estimator.status = status
        self.estimate = lambda: (t_s, np.zeros(3))
        RunLoop._follow_estimate(self)


def test_rejected_imu_samples_hold_the_replans_until_they_pass_again():
    loop = Loop()
    loop.follow(1.5)
    loop.follow(1.6, Status.IMU_ANGLE_REJECTED)
    loop.follow(1.7, Status.IMU_RATE_REJECTED | Status.IMU_ACCEL_REJECTED)
    assert loop.schedule == "schedule 0.50"  # the schedule in force plays on
    loop.follow(1.9)
    assert loop.updates == pytest.approx([0.5, 0.9]) and loop.schedule == "schedule 0.90"
    assert [kind for kind, _ in loop.lines] == ["notice", "replan"]  # told once, then resumed
    assert "re-plans held at t = 1.60 s" in loop.lines[0][1]
    assert loop.lines[1][1] == "resumed: held 0.30 s"


def test_an_open_loop_maneuver_is_not_held_nor_told():
    loop = Loop()
    loop.maneuver.target.closed_loop = False
    loop.follow(1.6, Status.IMU_ANGLE_REJECTED)
    assert loop.updates == pytest.approx([0.6]) and loop.lines == []
