"""The run's progress line shows what the scene measures: the D-bar's tilt, a body frame's
attitude, neither for a scene without them."""

import math

from gyrohost.commands.run import Progress
from gyrohost.run.ticker import Readout


def test_a_body_frame_adds_its_roll_pitch_yaw_in_degrees_after_the_estimators_status():
    readout = Readout(0.25, (74.9, -74.9, -74.9, 74.9), "ok", (0.1, -0.25, math.pi))
    line = Progress().line("schedule", 1.5, 0.5, readout)
    assert line.endswith("| tilt +0.250 rad | wheels +74.9 -74.9 -74.9 +74.9 rad/s | EKF ok"
                         " | roll pitch yaw   +5.7  -14.3 +180.0 deg"), line  # fmt: skip


def test_without_a_measure_or_an_estimate_the_line_is_as_before():
    line = Progress().line("spinup", 0.2, 0.0, Readout(math.nan, None, "off"))
    assert line.endswith("spinup   t   0.20 s | EKF off"), line
