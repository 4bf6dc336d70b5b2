"""The maneuver a run plans: what the rig's configuration says it moves and how it re-plans."""

import pytest

from gyrohost.config import load_rig_config
from gyrohost.control.maneuver import Target
from gyrohost.estimator.config import for_rig
from gyrohost.resources import shipped
from gyrohost.run import request


@pytest.mark.parametrize(
    ("config", "named", "strings"),
    [
        ("prism-sim-rig", None, ("s7",)),  # the scene schedules no string; a servo winds s7
        ("sim-rig", None, ("s13", "s24")),
        ("sim-rig", ("s13",), ("s13",)),  # the target's own choice stands
    ],
)
def test_an_attitude_moves_the_strings_the_servos_wind_in_real_time(
    monkeypatch, config, named, strings
):
    rig = load_rig_config(shipped("config", config))
    monkeypatch.setattr(request, "Maneuver", lambda model, limits, target: target)
    target = Target(attitude_rpy_rad=(0.01, 0.0, 0.0), strings=named)
    planned = request.planned_maneuver(rig, target, for_rig(rig))
    assert planned.strings == strings and planned.real_time
    assert planned.actuator_lag_s == request.actuator_lag(for_rig(rig), "both")
