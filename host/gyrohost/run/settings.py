"""What a run is given (:class:`RunSettings`) and how it ended (:class:`RunResult`)."""

from dataclasses import asdict, dataclass, field
from pathlib import Path

from gyrohost.config import LOOP_RATE_HZ, RunTable


@dataclass(frozen=True)
class RunSettings:
    """Timing, thresholds and limits of a run (SI units); the limits' defaults are those of the
    rig configuration's ``[run]`` table (:class:`gyrohost.config.RunTable`)."""

    rate_hz: float = LOOP_RATE_HZ
    servo_rate_hz: float = 25.0
    telemetry_div: int = 20
    """Wheel-board TELEMETRY every this many 1 kHz ticks (20: 50 Hz)."""
    heartbeat_ms: int = 500
    """Wheel-board fail-safe time-out: no frame from the host this long stops the wheels, ms."""
    spinup_timeout_s: float = RunTable.spinup_timeout_s
    steady_tolerance_rad_s: float = RunTable.steady_tolerance_rad_s
    steady_hold_s: float = 0.3
    lead_in_s: float = 0.5
    settle_s: float = 0.5
    stop_threshold_rad_s: float = RunTable.stop_threshold_rad_s
    """Wheels count as stopped below this speed, or once the board has switched them off."""
    rampdown_timeout_s: float = RunTable.rampdown_timeout_s
    imu_silence_s: float = RunTable.imu_silence_s
    wheel_silence_s: float = RunTable.wheel_silence_s
    max_tilt_rad: float = RunTable.max_tilt_rad
    """Largest |tilt| of the estimate, rad; off by default: the simulated D-bar floats free and
    keeps turning after the maneuver (set it on a rig whose supports bound the tilt)."""
    wheel_speed_margin_rad_s: float = RunTable.wheel_speed_margin_rad_s
    wheel_command_memory_s: float = 1.0
    """The wheel-speed limit is the largest command of this last stretch plus the margin: after
    a step down the board ramps (ACCEL_RAD_S2) and the wheel follows with its lag."""
    max_wheel_speed_rad_s: float = RunTable.max_wheel_speed_rad_s
    max_servo_load: float = RunTable.max_servo_load
    max_fused_per_tick: int = 4
    """Samples of one device fused per tick at most (the newest); older ones are only logged."""
    estimate_max_age_s: float = 0.03
    """The tick logs the estimate at its own time, the newest sample's (a prediction to the
    tick would cost a tenth of the loop); one this much older is predicted to the tick, so
    silent sources time out, s."""
    max_schedule_s: float = 600.0
    """Longest schedule a run plays, s (ten minutes: thirty times the longest shipped schedule,
    ``identify``'s 19.7 s, and about 0.7 GB of log at the simulated rig's 1.2 MB/s); a longer
    one is refused before anything moves, as more likely a mistake (milliseconds written as
    seconds) than a plan. ``gyrotens run --max-duration`` sets another."""
    estimator_max_lag_s: float = 1.0
    """The estimator runs in its own process; its newest estimate this far behind the loop
    ends the run (the limits and a maneuver would act on a stale estimate), s."""

    @classmethod
    def for_rig(cls, config) -> "RunSettings":
        """The defaults with the limits of ``config``'s ``[run]`` table (a ``RigConfig``)."""
        return cls(**asdict(config.run))

    def __post_init__(self):
        for name, value in asdict(self).items():
            if not value > 0:  # NaN fails too
                raise ValueError(f"run settings: {name} must be a positive number, got {value}")


@dataclass
class RunResult:
    """How a run ended.

    Attributes
    ----------
    completed : bool
        The schedule ran to its end (the safe state was then reached as the normal end).
    reason : str
        Why the run ended (``"completed"``, the fault, ``"interrupted (Ctrl-C)"``,
        ``"interrupted (SIGTERM)"``).
    exit_status : int
        0 completed and logged, 1 fault, limit, time-out or a log write refused, 128 + signal
        for an interrupt (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP).
    log_folder : Path
    summary : dict
        Also written to the log's ``meta.json`` under ``summary``.
    """

    completed: bool
    reason: str
    exit_status: int
    log_folder: Path
    summary: dict = field(default_factory=dict)
