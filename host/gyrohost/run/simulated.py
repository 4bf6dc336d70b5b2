"""A run on the simulated rig: its process started beside the estimator's, its ptys as the ports."""

from dataclasses import replace
from pathlib import Path

from gyrohost.control.maneuver import Maneuver
from gyrohost.control.schedule import Schedule
from gyrohost.run.limits import check_schedule
from gyrohost.run.sequence import RunLoop
from gyrohost.run.settings import RunResult, RunSettings
from gyrohost.simrig.process import RigProcess


def run_simulated(
    config, schedule: Schedule | Maneuver, log_folder, scene=None, **kwargs
) -> RunResult:
    """Start the simulated rig in a child process (real-time clock) and run on its ptys.

    Parameters
    ----------
    config : RigConfig
        Ports are replaced by the rig's pseudo-terminals; ``sim`` tables configure the rig.
    schedule : Schedule or Maneuver
    log_folder : path
    scene : path, optional
        Scene of the estimator, and of the rig's truth unless ``[sim.truth] scene`` sets another
        (default: the configuration's).
    **kwargs
        Passed on to :class:`RunLoop` (``settings``, ``estimator``, ``on_tick``, ``progress``,
        ``meta``, ``live``).
    """
    if scene is not None:
        config = replace(config, scene=str(Path(scene).resolve()))
    settings = kwargs.get("settings") or RunSettings()
    check_schedule(getattr(schedule, "schedule", schedule), config.servos.servo, config.run,
                   settings.max_schedule_s)  # fmt: skip
    loop = RunLoop(config, schedule, log_folder, **kwargs)  # checked before anything starts
    loop.spawn_estimator()  # its child and the rig's import side by side
    try:
        with RigProcess(config, period_s=1.0 / settings.rate_hz) as rig:
            loop.attach_rig(rig)
            return loop.run()
    finally:
        loop.end_estimator()
