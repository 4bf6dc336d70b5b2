"""Model-based string schedules and the closed loop of the D-bar tilt maneuver.

Typical use::

    from gyrotensegrity import Model, load_scene
    from gyrohost.control import Limits, Planner, Replanner, load_schedule, plan, preset
    from gyrohost.resources import shipped

    model = Model(load_scene(shipped("scene", "dbar-gyro")))
    p = plan(model, target_tilt_rad=-0.3, duration_s=4.0, limits=Limits(max_speed_m_s=0.05))
    p.schedule.save("schedules/tilt-0.3.toml")       # gyrotens run --schedule FILE
    u = p.schedule.input_at(model, t)                 # the model's input at t

See ``docs/schedule.md``. ``python -m studies.control_compare`` prints the SIL figures.
"""

from .attitude import Attitude
from .attitude_planner import AttitudePlan, AttitudePlanner, plan_attitude
from .closed_loop import Replanner, ReplanRecord, TruthPlusNoise, ekf_estimate
from .errors import PlanError, ScheduleError
from .planner import Plan, Planner, Weights, plan
from .presets import PRESETS, preset
from .reduced import DBarReduced
from .schedule import Limits, Schedule, load_schedule, schedule_from_dict
from .shape_attitude import AttitudeModel

__all__ = [
    "PRESETS",
    "Attitude",
    "AttitudeModel",
    "AttitudePlan",
    "AttitudePlanner",
    "DBarReduced",
    "Limits",
    "Plan",
    "PlanError",
    "Planner",
    "ReplanRecord",
    "Replanner",
    "Schedule",
    "ScheduleError",
    "TruthPlusNoise",
    "Weights",
    "ekf_estimate",
    "load_schedule",
    "plan",
    "plan_attitude",
    "preset",
    "schedule_from_dict",
]
