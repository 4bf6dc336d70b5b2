"""A run as a user asks for it, checked whole before anything is opened, then run.

``gyrotens run`` parses its options into a :class:`RunRequest` and calls :func:`execute`; a
Python user does the same::

    from gyrohost.run.request import RunRequest, execute
    result = execute(RunRequest(config="sim-rig", schedule="paper", sim=True))

:func:`prepare` loads the configuration with its overlays and scenes, the estimator's keys and
what to play (a schedule file, a preset or a shipped schedule, or a planned tilt maneuver), and
checks the request's combinations and the log folder: every bad input is an error here, before a
port is opened or a log folder made.
"""

import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from gyrohost.control.maneuver import Maneuver, Target
from gyrohost.run.errors import RunRequestError
from gyrohost.run.settings import RunResult, RunSettings


@dataclass(frozen=True)
class RunRequest:
    """What to run, on which rig, logged where.

    Attributes
    ----------
    config : str or path
        The rig configuration: a file or a shipped name (``sim-rig``, ``lab-rig``).
    overlays : tuple of path
        TOML keys merged over the configuration, in order (``gyrotens identify`` writes them).
    scene, truth_scene : str or path, optional
        The host's scene (default: the configuration's) and, on the simulated rig only, the
        scene its truth runs.
    estimator : path, optional
        A TOML file whose ``[estimator]`` keys override the configuration's.
    schedule : str, optional
        A schedule file, a preset or a shipped schedule (default ``paper``); not with ``target``.
    target : Target, optional
        A tilt or attitude maneuver planned on the scene (and re-planned when
        ``target.closed_loop``).
    out : path, optional
        The new log folder (default ``out/runs/DATE-NAME``).
    sim : bool
        Start a simulated rig of the run's own; else the configuration's ports, ``ports_file``
        (a running ``gyrotens rig``) and ``ports`` (device -> path) say where the devices are.
    max_schedule_s : float, optional
        Longest schedule played, s (default: :attr:`RunSettings.max_schedule_s`).
    """

    config: str | Path = "sim-rig"
    overlays: tuple[Path, ...] = ()
    scene: str | Path | None = None
    truth_scene: str | Path | None = None
    estimator: Path | None = None
    schedule: str | None = None
    target: Target | None = None
    out: Path | None = None
    sim: bool = False
    ports_file: Path | None = None
    ports: dict[str, str] = field(default_factory=dict)
    max_schedule_s: float | None = None


@dataclass(frozen=True)
class PreparedRun:
    """A request loaded and checked: the configuration, the estimator's keys, what to play, the
    log folder (not yet made) and the run's settings."""

    config: object
    estimator: object
    schedule: object
    out: Path
    settings: RunSettings

    def duration_line(self) -> str:
        """What will play and for how long, against the longest allowed."""
        schedule = getattr(self.schedule, "schedule", self.schedule)
        return (
            f"schedule {schedule.name}: {schedule.t_end:g} s "
            f"(at most {self.settings.max_schedule_s:g} s allowed)"
        )


def prepare(request: RunRequest) -> PreparedRun:
    """Load and check everything ``request`` names; nothing is opened.

    Raises
    ------
    GyrohostError (a ValueError)
        A bad configuration, scene, schedule, estimator file, port or combination of them, or a
        log folder that exists; the message names the file or option.
    """
    from gyrohost.config import load_with_scene
    from gyrohost.estimator.config import for_rig
    from gyrohost.resources import resolve
    from gyrohost.run.log import check_new_log_folder
    from gyrohost.simrig.config import sim_config, with_truth_scene

    if request.truth_scene is not None and not request.sim:
        raise RunRequestError("--truth-scene is for the simulated rig: add --sim")
    if request.sim and request.ports_file is not None:
        raise RunRequestError(
            "give --sim (a rig of its own) or --rig PORTSFILE (a running rig), not both"
        )
    config = load_with_scene(resolve("config", request.config), request.overlays, request.scene)
    if request.truth_scene is not None:
        config = with_truth_scene(config, resolve("scene", request.truth_scene))
    if request.sim:
        sim_config(config)  # its [sim] tables checked before anything starts
    estimator = for_rig(config, request.estimator)
    schedule = what_to_play(config, request.schedule, request.target, estimator)
    if not request.sim:
        config = wired(config, request)
    out = Path(request.out or default_log_folder(schedule))
    check_new_log_folder(out)
    settings = RunSettings.for_rig(config)
    if request.max_schedule_s is not None:
        settings = replace(settings, max_schedule_s=request.max_schedule_s)
    return PreparedRun(config, estimator, schedule, out, settings)


def execute(
    request: RunRequest, progress=None, meta=None, live_port=None, on_live=None, announce=None
) -> RunResult:
    """Prepare ``request`` and run it, from connection to the safe state.

    ``progress`` is the run loop's status callback; ``meta`` extra keys for the log's
    ``meta.json``; ``live_port`` starts a Foxglove live view there, whose address goes to
    ``on_live(url)`` before the run starts; ``announce`` gets the schedule's duration line
    (:meth:`PreparedRun.duration_line`) once the request is checked. The result says how the run
    ended; every exit, an exception's too, leaves the rig in the safe state.
    """
    from gyrohost.drivers.portlock import claim_ports
    from gyrohost.run.devices import check_real_rig, device_ports
    from gyrohost.run.sequence import RunLoop
    from gyrohost.run.simulated import run_simulated

    run = prepare(request)
    if announce is not None:
        announce(run.duration_line())
    options = {"estimator": run.estimator, "progress": progress, "meta": meta or {}}
    options["settings"] = run.settings
    try:
        if live_port is not None:
            options["live"] = _live_view(run.config, live_port, on_live)
        if request.sim:
            return run_simulated(run.config, run.schedule, run.out, **options)
        loop = RunLoop(run.config, run.schedule, run.out, **options)
        check_real_rig(loop.config)  # after the loop checked the scene, schedule, estimator
        with claim_ports(device_ports(loop.config)):  # before a log folder or a byte sent
            return loop.run()
    finally:
        if "live" in options:
            options["live"].close()  # also when the run never started


def _live_view(config, port: int, on_live):
    """The live view's server on the configuration's scene, its address told."""
    from gyrohost.run.live import LiveView
    from gyrotensegrity import load_scene

    live = LiveView(load_scene(config.scene_path), port)
    if on_live is not None:
        on_live(live.url)
    return live


def what_to_play(config, schedule: str | None, target: Target | None, estimator):
    """A Schedule (``schedule``, default the paper preset) or a Maneuver (``target``)."""
    if target is None:
        return load_schedule_arg(schedule or "paper", config.scene_path)
    if schedule is not None:
        raise RunRequestError("give --schedule or a target (--target-tilt, ...), not both")
    return planned_maneuver(config, target, estimator)


def planned_maneuver(config, target: Target, estimator) -> Maneuver:
    """The maneuver to ``target`` on the configuration's scene, within its servos' limits and
    its ``[run] max_wheel_speed_rad_s``; an attitude's re-plans allow for the lag of what it
    moves (the estimator's ``servo_lag_s``, ``wheel_lag_s``: the rig's) and are bounded by
    their period (a run is real time); it moves the strings the configuration's servos wind
    (unless the target names them), which need not be those the scene schedules."""
    from gyrohost.control.schedule import Limits
    from gyrotensegrity import Model, load_scene

    limits = Limits.per_string(config.servos.servo)
    if target.attitude_rpy_rad is not None:  # a tilt holds the wheels at the scene's spins
        limits = replace(limits, max_wheel_speed_rad_s=config.run.max_wheel_speed_rad_s)
        lag_s = actuator_lag(estimator, target.mode)
        wound = tuple(s.string for s in config.servos.servo if s.string)
        strings = target.strings if target.strings is not None else wound
        target = replace(target, actuator_lag_s=lag_s, real_time=True, strings=strings)
    return Maneuver(Model(load_scene(config.scene_path)), limits, target)


def actuator_lag(estimator, mode: str) -> float:
    """The first-order lag, s, of what an attitude maneuver in ``mode`` moves: the servos'
    (``servo_lag_s``), the wheels' (``wheel_lag_s``), the larger for both."""
    lags = {"strings": estimator.servo_lag_s, "wheels": estimator.wheel_lag_s}
    return lags.get(mode, max(lags.values()))


def load_schedule_arg(text: str, scene_path: Path):
    """A schedule file, else a preset built for the scene at ``scene_path``, else a shipped
    schedule of that name.

    Raises
    ------
    ScheduleError
        ``text`` is none of them (the message lists the presets and the shipped schedules).
    """
    from gyrohost.control.errors import ScheduleError
    from gyrohost.control.presets import PRESETS, preset
    from gyrohost.control.schedule import load_schedule
    from gyrohost.resources import ResourceError, resolve
    from gyrotensegrity import Model, load_scene

    if text in PRESETS and not Path(text).is_file():
        return preset(text, Model(load_scene(scene_path)))
    try:
        return load_schedule(resolve("schedule", text))
    except ResourceError as exc:
        raise ScheduleError(f"{exc}; presets: {', '.join(PRESETS)}") from None


def wired(config, request: RunRequest):
    """``config`` with the ports of ``request`` (its ports file, then its single ports); every
    device must end on a real port, not the emulator's."""
    from gyrohost.config import EMULATED_PORT
    from gyrohost.run.connect import with_ports
    from gyrohost.simrig.control_socket import read_ports_file

    running = {} if request.ports_file is None else read_ports_file(request.ports_file).devices
    config = with_ports(config, dict(running) | {k: p for k, p in request.ports.items() if p})
    ports = {"imu": config.imu.port, "wheels": config.wheelboard.port, "servos": config.servos.port}
    emulated = [name for name, port in ports.items() if port == EMULATED_PORT]
    if emulated:
        raise RunRequestError(
            f"{request.config}: port(s) of {', '.join(emulated)} are '{EMULATED_PORT}': add "
            "--sim, or --rig PORTSFILE of a running 'gyrotens rig' (or its ptys with "
            "--imu/--wheels/--servos)"
        )
    return config


def default_log_folder(schedule) -> Path:
    """``out/runs/DATE-NAME``: NAME one safe path component (a schedule's name comes from a
    file; a maneuver's says its target and loop)."""
    from gyrohost.resources import safe_name

    target = getattr(schedule, "target", None)
    if target is None:
        name = safe_name(schedule.name)
    else:
        aim = (
            f"tilt{target.tilt_rad:+g}"
            if target.attitude_rpy_rad is None
            else "attitude" + "".join(f"{math.degrees(v):+.3g}" for v in target.attitude_rpy_rad)
        )
        name = f"{aim}-{'closed' if target.closed_loop else 'open'}"
    return Path("out/runs") / f"{time.strftime('%Y%m%d-%H%M%S')}-{name}"
