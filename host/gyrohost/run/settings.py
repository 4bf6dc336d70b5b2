"""What a run is given (:class:`RunSettings`) and how it ended (:class:`RunResult`)."""

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path


@dataclass(frozen=True)
class RunSettings:
    """Timing, thresholds and limits of a run (SI units)."""

    rate_hz: float = 100.0
    servo_rate_hz: float = 25.0
    telemetry_div: int = 20
    """Wheel-board TELEMETRY every this many 1 kHz ticks (20: 50 Hz)."""
    heartbeat_ms: int = 500
    """Wheel-board fail-safe time-out: no frame from the host this long stops the wheels, ms."""
    spinup_timeout_s: float = 10.0
    steady_tolerance_rad_s: float = 1.5
    steady_hold_s: float = 0.3
    lead_in_s: float = 0.5
    settle_s: float = 0.5
    stop_threshold_rad_s: float = 3.0
    """Wheels count as stopped below this speed, or once the board has switched them off."""
    rampdown_timeout_s: float = 5.0
    imu_silence_s: float = 0.5
    wheel_silence_s: float = 0.5
    max_tilt_rad: float = math.inf
    """Largest |tilt| of the estimate, rad; off by default: the simulated D-bar floats free and
    keeps turning after the maneuver (set it on a rig whose supports bound the tilt)."""
    wheel_speed_margin_rad_s: float = 15.0
    max_servo_load: float = 0.95
    max_fused_per_tick: int = 4
    """Samples of one device fused per tick at most (the newest); older ones are only logged."""

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
