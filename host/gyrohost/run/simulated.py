"""A run on the simulated rig, and a configuration's ports replaced by a rig's ptys."""

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
    with RigProcess(config, period_s=1.0 / settings.rate_hz) as rig:
        return RunLoop(with_ports(config, rig.paths), schedule, log_folder, rig=rig, **kwargs).run()


def with_ports(config, ports: dict):
    """``config`` with device ports replaced: ``ports`` maps ``imu``, ``wheels``, ``servos`` to a
    path (a missing or ``None`` entry keeps the configured port)."""
    return replace(
        config,
        imu=replace(config.imu, port=ports.get("imu") or config.imu.port),
        wheelboard=replace(config.wheelboard, port=ports.get("wheels") or config.wheelboard.port),
        servos=replace(config.servos, port=ports.get("servos") or config.servos.port),
    )
