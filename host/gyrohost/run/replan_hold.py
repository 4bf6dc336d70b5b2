"""When a closed loop may re-plan from the estimate: only while the IMU still corrects it.

A filter whose process model misses what turns the structure (a truth with the motors'
reaction, docs/attitude-plans.md) rejects every IMU sample and diverges; re-plans from its
estimate would then steer the rig by the model's error. Held, the schedule in force plays on,
as open loop, until the IMU's samples pass their gates again.
"""

import math

from gyrohost.estimator.ekf import Status

UNFOLLOWABLE = (
    Status.IMU_RATE_REJECTED
    | Status.IMU_ACCEL_REJECTED
    | Status.IMU_ANGLE_REJECTED
    | Status.PREDICTION_ONLY
)
"""Status bits of an estimate a closed loop does not re-plan from."""


def followable(status: Status) -> bool:
    """Whether a closed loop may re-plan from an estimate of this status word: its last IMU
    sample passed every gate and not every source timed out (the estimate is more than the
    model's own prediction)."""
    return not Status(status) & UNFOLLOWABLE


class ReplanHold:
    """Holds a closed loop's re-plans while its estimates are not :func:`followable`.

    A single rejected sample (one in a thousand at the gates' probability) only delays a re-plan
    to the next estimate; a hold that lasts a re-planning period ``period_s`` is told once
    through ``notice(message)``, and its end through ``event(kind, message)``.
    """

    def __init__(self, period_s: float, notice, event):
        self.period_s, self.notice, self.event = period_s, notice, event
        self.since_s = math.nan
        self.told = False

    def follow(self, t_s: float, status: Status) -> bool:
        """Whether to re-plan from the estimate of time ``t_s`` (s) and status word ``status``."""
        if followable(status):
            if self.told:
                self.event("replan", f"resumed: held {t_s - self.since_s:.2f} s")
            self.since_s, self.told = math.nan, False
            return True
        if math.isnan(self.since_s):
            self.since_s = t_s
        if not self.told and t_s - self.since_s >= self.period_s:
            self.notice(
                f"closed loop: re-plans held since t = {self.since_s:.2f} s, the estimate's IMU "
                "samples fail their gates; the schedule in force plays on"
            )
            self.told = True
        return False
