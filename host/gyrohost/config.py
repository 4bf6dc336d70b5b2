"""Rig configuration: TOML file -> frozen dataclasses, with every default in this module.

The file layout is described in ``docs/rig-config.md``; every table maps onto one dataclass
below, read and checked by :mod:`gyrohost.configfile`. Two tables are kept as read, for the
part that knows their keys: ``[estimator]`` (:func:`gyrohost.estimator.config.for_rig`) and
``[sim]``, the simulated rig's devices and truth (:mod:`gyrohost.simrig.config`), which a real
rig's file leaves out.
"""

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

from gyrohost.configfile import build, spec
from gyrohost.errors import ConfigError
from gyrohost.overlay import merge_overlay
from gyrohost.resources import ResourceError, resolve
from gyrotensegrity.textfile import read_toml

EMULATED_PORT = "emulator"
"""Port value meaning: start the device emulator and use its pseudo-terminal."""

MX_POSITION_LIMIT = 28672
"""Largest magnitude of an MX-12W multi-turn position, steps (7 turns at divider 1)."""


@dataclass(frozen=True)
class ImuConfig:
    """WitMotion BWT61CL link and mounting."""

    port: str = "/dev/rfcomm0"
    baud: int = field(default=115200, metadata=spec(choices=(9600, 115200)))
    rate_hz: int = field(default=100, metadata=spec(choices=(20, 100)))
    mounting: str = field(default="horizontal", metadata=spec(choices=("horizontal", "vertical")))
    mounting_rpy_rad: tuple[float, float, float] = field(
        default=(0.0, 0.0, 0.0), metadata=spec(lo=-math.pi, hi=math.pi)
    )
    timeout_s: float = field(default=0.1, metadata=spec(lo=0.001, hi=10.0))


@dataclass(frozen=True)
class ServoConfig:
    """One string servo: Dynamixel ID, pulley calibration, hard limits."""

    name: str
    id: int = field(metadata=spec(lo=0, hi=252))
    pulley_radius_m: float = field(metadata=spec(lo=1e-4, hi=0.1))
    zero_position: int = field(
        default=0, metadata=spec(lo=-MX_POSITION_LIMIT, hi=MX_POSITION_LIMIT)
    )
    length_at_zero_m: float = field(default=0.0, metadata=spec(lo=0.0, hi=10.0))
    length_sign: int = field(default=1, metadata=spec(choices=(-1, 1)))
    min_length_m: float = field(default=0.0, metadata=spec(lo=0.0, hi=10.0))
    max_length_m: float = field(default=1.0, metadata=spec(lo=0.0, hi=10.0))
    max_speed_m_s: float = field(default=0.05, metadata=spec(lo=1e-4, hi=2.0))
    string: str = field(default="", metadata=spec(doc="scene string it winds; '' = none"))

    def problems(self) -> list[tuple[str, str]]:
        if self.min_length_m >= self.max_length_m:
            return [("min_length_m", "must be smaller than max_length_m")]
        return []


@dataclass(frozen=True)
class ServoBusConfig:
    """The Dynamixel bus (U2D2 adapter) and its servos."""

    port: str = "/dev/ttyUSB0"
    baud: int = field(
        default=1_000_000, metadata=spec(choices=(57600, 115200, 500000, 1_000_000, 2_000_000))
    )
    read_mode: str = field(default="bulk", metadata=spec(choices=("bulk", "per_servo")))
    reply_timeout_s: float = field(default=0.034, metadata=spec(lo=0.001, hi=1.0))
    servo: tuple[ServoConfig, ...] = ()

    def problems(self) -> list[tuple[str, str]]:
        ids = [s.id for s in self.servo]
        if len(set(ids)) != len(ids):
            return [("servo", f"duplicate servo IDs in {ids}")]
        return []


@dataclass(frozen=True)
class WheelboardConfig:
    """Wheel board link (fields beyond port and baud belong to the wheel-board driver)."""

    port: str = "/dev/ttyACM0"
    baud: int = field(default=1_000_000, metadata=spec(lo=1200, hi=4_000_000))


IMU_FRAME_NODES = ("n1", "n3", "n2")
"""Where the D-bar's IMU sits: the three scene nodes of its frame (x along n1 -> n3, z along x
cross (n2 - n1)); the default of the rig's truth and of the estimator alike."""


@dataclass(frozen=True)
class StartCheckConfig:
    """How far the measured state may be from the scene's initial state when a run connects,
    before anything moves (``gyrohost.run.start_check``); beyond, the run is refused."""

    attitude_rad: float = field(default=0.1, metadata=spec(lo=0.0, hi=math.pi))
    rate_rad_s: float = field(default=0.05, metadata=spec(lo=0.0, hi=100.0))
    length_m: float = field(default=0.005, metadata=spec(lo=0.0, hi=10.0))
    wheel_speed_rad_s: float = field(default=1.0, metadata=spec(lo=0.0, hi=1000.0))


LOOP_RATE_HZ = 100.0
"""The run loop's tick rate (``gyrohost.run.settings.RunSettings.rate_hz``), Hz: the servos get
their goals at every tick."""


@dataclass(frozen=True)
class RunTable:
    """The ``[run]`` table: limits of a run on this rig (``gyrohost.run.settings.RunSettings``
    takes its defaults from here). Beyond a limit the run ends in the safe state, exit status 1."""

    max_tilt_rad: float = field(
        default=math.inf, metadata=spec(lo=1e-3, hi=math.pi, doc="absent = unchecked")
    )
    imu_silence_s: float = field(default=0.5, metadata=spec(lo=0.01, hi=10.0))
    wheel_silence_s: float = field(default=0.5, metadata=spec(lo=0.01, hi=10.0))
    wheel_speed_margin_rad_s: float = field(default=15.0, metadata=spec(lo=0.1, hi=1000.0))
    max_wheel_speed_rad_s: float = field(
        default=150.0, metadata=spec(lo=0.1, hi=1000.0, doc="largest |spin| a schedule commands")
    )
    max_servo_load: float = field(default=0.95, metadata=spec(lo=0.01, hi=1.0))
    spinup_timeout_s: float = field(default=10.0, metadata=spec(lo=0.1, hi=600.0))
    steady_tolerance_rad_s: float = field(default=1.5, metadata=spec(lo=0.01, hi=100.0))
    stop_threshold_rad_s: float = field(default=3.0, metadata=spec(lo=0.01, hi=100.0))
    rampdown_timeout_s: float = field(default=5.0, metadata=spec(lo=0.1, hi=600.0))

    def problems(self) -> list[tuple[str, str]]:
        if self.steady_tolerance_rad_s >= self.wheel_speed_margin_rad_s:
            return [
                ("steady_tolerance_rad_s", "must be smaller than wheel_speed_margin_rad_s "
                 "(wheels counted steady would be beyond the speed limit)")
            ]  # fmt: skip
        return []


@dataclass(frozen=True)
class RigConfig:
    """The whole rig. ``source`` is set by the loader (the file read), never by the file."""

    scene: str = "dbar-gyro"
    imu: ImuConfig = ImuConfig()
    servos: ServoBusConfig = ServoBusConfig()
    wheelboard: WheelboardConfig = WheelboardConfig()
    sim: dict = field(default_factory=dict, metadata=spec(doc="gyrohost.simrig.config"))
    estimator: dict = field(default_factory=dict, metadata=spec(doc="the EKF's keys"))
    start_check: StartCheckConfig = StartCheckConfig()
    run: RunTable = RunTable()
    source: str = field(default="<defaults>", metadata={"internal": True})

    def problems(self) -> list[tuple[str, str]]:
        if self.run.max_tilt_rad <= self.start_check.attitude_rad:
            return [
                ("run.max_tilt_rad", f"{self.run.max_tilt_rad:g} rad must exceed start_check."
                 f"attitude_rad {self.start_check.attitude_rad:g} rad (a run allowed to start "
                 "would break the limit at once)")
            ]  # fmt: skip
        return []

    @property
    def base_dir(self) -> Path:
        """Folder that relative paths in the file start from: the file's own, else the cwd."""
        return Path(self.source).parent if self.source.endswith(".toml") else Path.cwd()

    @property
    def scene_path(self) -> Path:
        """Scene file: ``scene`` relative to the configuration file's folder, else a shipped
        scene of that name (:func:`gyrohost.resources.resolve`).

        Raises
        ------
        ConfigError
            ``scene`` is neither (the message names the file, the key and the shipped scenes).
        """
        return self.resolve_scene("scene", self.scene)

    def resolve_scene(self, key: str, value: str) -> Path:
        """The scene ``value`` of the file's ``key``, as :attr:`scene_path` resolves it."""
        try:
            return resolve("scene", value, self.base_dir)
        except ResourceError as exc:
            raise ConfigError(f"{self.source}: key '{key}': {exc}") from None


def load_rig_config(path: str | Path, overlays=()) -> RigConfig:
    """Read and validate a rig configuration TOML file, with ``overlays`` (files, in order)
    merged into it (:func:`gyrohost.overlay.merge_overlay`); relative paths stay relative to
    ``path``.

    Raises
    ------
    ConfigError
        A file is missing or not TOML, an overlay does not fit the configuration, or a key is
        unknown, mistyped, out of range or missing (naming the overlays that were merged).
    """
    data = read_toml(path, ConfigError)
    for overlay in overlays:
        data = merge_overlay(data, read_toml(overlay, ConfigError), str(overlay))
    if not overlays:
        return rig_config_from_dict(data, str(path))
    try:
        return rig_config_from_dict(data, str(path))
    except ConfigError as exc:
        merged = ", ".join(map(str, overlays))
        raise ConfigError(f"{exc} (with the overlay {merged} merged)") from None


def load_with_scene(path, overlays=(), scene=None) -> RigConfig:
    """:func:`load_rig_config` with the host's scene replaced where given (a file or a shipped
    name, as ``--scene`` takes it).

    Raises
    ------
    ConfigError, ResourceError
        As :func:`load_rig_config`; a scene that is neither a file nor a shipped name.
    """
    config = load_rig_config(path, overlays)
    if scene is not None:
        config = replace(config, scene=str(resolve("scene", scene)))
    return config


def rig_config_from_dict(data: dict, source: str = "<dict>") -> RigConfig:
    """Build a :class:`RigConfig` from parsed TOML ``data``; ``source`` names it in errors."""
    return replace(build(RigConfig, data, "", source), source=source)


__all__ = [
    "EMULATED_PORT",
    "IMU_FRAME_NODES",
    "LOOP_RATE_HZ",
    "MX_POSITION_LIMIT",
    "ConfigError",
    "ImuConfig",
    "RigConfig",
    "RunTable",
    "ServoBusConfig",
    "ServoConfig",
    "StartCheckConfig",
    "WheelboardConfig",
    "load_rig_config",
    "load_with_scene",
    "rig_config_from_dict",
]
