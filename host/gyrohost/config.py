"""Rig configuration: TOML file -> frozen dataclasses, with every default in this module.

The file layout is described in ``docs/rig-config.md``. Every table maps onto one dataclass below;
a key the dataclass does not have, a value of the wrong type or outside its range raises
:class:`ConfigError` naming the file and the dotted key (``servos.servo[1].pulley_radius_m``).

Range and choice constraints live in each field's metadata (``min``, ``max``, ``choices``) so the
loader checks them all the same way; cross-field rules live in each class's ``problems`` method.
"""

import math
import typing
from dataclasses import MISSING, dataclass, field, fields, is_dataclass, replace
from pathlib import Path

from gyrohost.errors import ConfigError
from gyrohost.overlay import merge_overlay
from gyrohost.resources import ResourceError, resolve
from gyrotensegrity.textfile import read_toml

EMULATED_PORT = "emulator"
"""Port value meaning: start the device emulator and use its pseudo-terminal."""

MX_POSITION_LIMIT = 28672
"""Largest magnitude of an MX-12W multi-turn position, steps (7 turns at divider 1)."""


def _spec(*, lo=None, hi=None, choices=None, doc: str = "") -> dict:
    return {"min": lo, "max": hi, "choices": choices, "doc": doc}


@dataclass(frozen=True)
class StreamFaultConfig:
    """Faults applied to the bytes an emulator sends (see ``gyrohost.simrig.faults``)."""

    corrupt_byte_prob: float = field(default=0.0, metadata=_spec(lo=0.0, hi=1.0))
    drop_byte_prob: float = field(default=0.0, metadata=_spec(lo=0.0, hi=1.0))
    silent: bool = False
    stall_period_s: float = field(default=0.0, metadata=_spec(lo=0.0, doc="0 = never"))
    stall_duration_s: float = field(default=0.0, metadata=_spec(lo=0.0))
    seed: int = field(default=0, metadata=_spec(lo=0))

    def problems(self) -> list[tuple[str, str]]:
        if self.stall_period_s > 0 and self.stall_duration_s >= self.stall_period_s:
            return [("stall_duration_s", "must be shorter than stall_period_s")]
        return []


@dataclass(frozen=True)
class ImuConfig:
    """WitMotion BWT61CL link and mounting."""

    port: str = "/dev/rfcomm0"
    baud: int = field(default=115200, metadata=_spec(choices=(9600, 115200)))
    rate_hz: int = field(default=100, metadata=_spec(choices=(20, 100)))
    mounting: str = field(default="horizontal", metadata=_spec(choices=("horizontal", "vertical")))
    mounting_rpy_rad: tuple[float, float, float] = field(
        default=(0.0, 0.0, 0.0), metadata=_spec(lo=-math.pi, hi=math.pi)
    )
    timeout_s: float = field(default=0.1, metadata=_spec(lo=0.001, hi=10.0))


@dataclass(frozen=True)
class ServoConfig:
    """One string servo: Dynamixel ID, pulley calibration, hard limits."""

    name: str
    id: int = field(metadata=_spec(lo=0, hi=252))
    pulley_radius_m: float = field(metadata=_spec(lo=1e-4, hi=0.1))
    zero_position: int = field(
        default=0, metadata=_spec(lo=-MX_POSITION_LIMIT, hi=MX_POSITION_LIMIT)
    )
    length_at_zero_m: float = field(default=0.0, metadata=_spec(lo=0.0, hi=10.0))
    length_sign: int = field(default=1, metadata=_spec(choices=(-1, 1)))
    min_length_m: float = field(default=0.0, metadata=_spec(lo=0.0, hi=10.0))
    max_length_m: float = field(default=1.0, metadata=_spec(lo=0.0, hi=10.0))
    max_speed_m_s: float = field(default=0.05, metadata=_spec(lo=1e-4, hi=2.0))
    string: str = field(default="", metadata=_spec(doc="scene string it winds; '' = none"))

    def problems(self) -> list[tuple[str, str]]:
        if self.min_length_m >= self.max_length_m:
            return [("min_length_m", "must be smaller than max_length_m")]
        return []


@dataclass(frozen=True)
class ServoBusConfig:
    """The Dynamixel bus (U2D2 adapter) and its servos."""

    port: str = "/dev/ttyUSB0"
    baud: int = field(
        default=1_000_000, metadata=_spec(choices=(57600, 115200, 500000, 1_000_000, 2_000_000))
    )
    read_mode: str = field(default="bulk", metadata=_spec(choices=("bulk", "per_servo")))
    reply_timeout_s: float = field(default=0.034, metadata=_spec(lo=0.001, hi=1.0))
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
    baud: int = field(default=1_000_000, metadata=_spec(lo=1200, hi=4_000_000))


@dataclass(frozen=True)
class ImuEmuConfig:
    """Simulated BWT61CL: MPU6050-like noise (datasheet densities), bias, temperature."""

    gyro_noise_density_rad_s_rthz: float = field(
        default=math.radians(0.005), metadata=_spec(lo=0.0, hi=1.0)
    )
    accel_noise_density_m_s2_rthz: float = field(
        default=400e-6 * 9.80665, metadata=_spec(lo=0.0, hi=10.0)
    )
    gyro_bias_std_rad_s: float = field(default=math.radians(0.5), metadata=_spec(lo=0.0, hi=1.0))
    accel_bias_std_m_s2: float = field(default=0.05, metadata=_spec(lo=0.0, hi=5.0))
    angle_noise_std_rad: float = field(default=math.radians(0.05), metadata=_spec(lo=0.0, hi=0.5))
    temperature_degC: float = field(default=25.0, metadata=_spec(lo=-40.0, hi=85.0))
    seed: int = field(default=1, metadata=_spec(lo=0))
    faults: StreamFaultConfig = StreamFaultConfig()


@dataclass(frozen=True)
class ServoEmuConfig:
    """Simulated MX-12W bus: motor figures and servo-level faults."""

    return_delay_us: int = field(default=20, metadata=_spec(lo=0, hi=508))
    no_load_speed_rpm: float = field(default=470.0, metadata=_spec(lo=1.0, hi=1000.0))
    stall_torque_N_m: float = field(default=0.2, metadata=_spec(lo=1e-3, hi=10.0))
    overload_ids: tuple[int, ...] = field(default=(), metadata=_spec(lo=0, hi=252))
    no_reply_ids: tuple[int, ...] = field(default=(), metadata=_spec(lo=0, hi=252))
    # a servo at rest stops anywhere within this many steps of its goal (uniform): its shaft
    # is continuous, its encoder reads a count (0.5: within the count its read shows)
    hold_band_steps: float = field(default=0.5, metadata=_spec(lo=0.0, hi=10.0))
    seed: int = field(default=3, metadata=_spec(lo=0, doc="of the positions where servos stop"))
    faults: StreamFaultConfig = StreamFaultConfig()


WHEEL_KINDS = ("emulator", "simavr")
"""Simulated wheel boards: the Python emulator, or the real firmware ELF in the simavr harness."""


@dataclass(frozen=True)
class WheelEmuConfig:
    """Simulated wheel board: which one, speed response of the motors, ripple, stream faults.

    ``kind = "simavr"`` runs the real firmware in the FIL harness (docs/fil.md); the emulator's
    motor and fault keys then do not apply, ``spin_sign`` does for both kinds.
    """

    time_constant_s: float = field(default=0.05, metadata=_spec(lo=1e-4, hi=10.0))
    coast_time_constant_s: float = field(default=5.0, metadata=_spec(lo=1e-3, hi=1000.0))
    ripple_fraction: float = field(default=0.0, metadata=_spec(lo=0.0, hi=0.5))
    ripple_per_rev: int = field(default=1, metadata=_spec(lo=1, hi=100))
    speed_error_std_rad_s: float = field(
        default=0.01, metadata=_spec(lo=0.0, hi=10.0, doc="the speed loop's error, stationary std")
    )
    seed: int = field(default=2, metadata=_spec(lo=0, doc="of the speed error"))
    faults: StreamFaultConfig = StreamFaultConfig()
    kind: str = field(default="emulator", metadata=_spec(choices=WHEEL_KINDS))
    spin_sign: tuple[int, int, int, int] = field(
        default=(1, 1, 1, 1), metadata=_spec(choices=(-1, 1), doc="board wheel i -> scene spin")
    )
    simavr_elf: str = field(default="", metadata=_spec(doc="'' = $GYROTENS_FIRMWARE_BUILD/avr"))
    simavr_harness: str = field(default="", metadata=_spec(doc="'' = $GYROTENS_FIRMWARE_BUILD/sim"))
    simavr_options: tuple[str, ...] = ()

    def problems(self) -> list[tuple[str, str]]:
        if self.kind == "simavr" and self.faults != StreamFaultConfig():
            return [("faults", "stream faults need kind = 'emulator' (simavr's pty is direct)")]
        return []


IMU_FRAME_NODES = ("n1", "n3", "n2")
"""Where the D-bar's IMU sits: the three scene nodes of its frame (x along n1 -> n3, z along x
cross (n2 - n1)); the default of the rig's truth and of the estimator alike."""


@dataclass(frozen=True)
class TruthConfig:
    """The rig's truth model: step, IMU attachment and deliberate model mismatch.

    ``scene``, ``imu_rotation_deg`` and ``servo_zero_offset_rad`` make the truth differ from what
    the host knows (its scene, ``imu.mounting_rpy_rad``, the servos' ``zero_position``), as a real
    rig differs from its model; ``gyrohost.simrig.truth`` applies them.
    """

    dt_s: float = field(default=0.005, metadata=_spec(lo=1e-4, hi=0.02))
    imu_frame_nodes: tuple[str, str, str] = IMU_FRAME_NODES
    imu_gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.80665)
    wheel_inertia_scale: float = field(default=1.0, metadata=_spec(lo=0.1, hi=10.0))
    servo_lag_s: float = field(default=0.0, metadata=_spec(lo=0.0, hi=10.0))
    imu_latency_s: float = field(default=0.0, metadata=_spec(lo=0.0, hi=1.0))
    scene: str = field(default="", metadata=_spec(doc="scene the truth runs; '' = the config's"))
    imu_rotation_deg: tuple[float, float, float] = field(
        default=(0.0, 0.0, 0.0), metadata=_spec(lo=-180.0, hi=180.0)
    )
    servo_zero_offset_rad: tuple[float, ...] = field(
        default=(), metadata=_spec(lo=-math.pi, hi=math.pi, doc="per [[servos.servo]]; [] = 0")
    )


@dataclass(frozen=True)
class SimConfig:
    """Parameters of the simulated devices (used only for ports set to ``"emulator"``)."""

    imu: ImuEmuConfig = ImuEmuConfig()
    servos: ServoEmuConfig = ServoEmuConfig()
    wheels: WheelEmuConfig = WheelEmuConfig()
    truth: TruthConfig = TruthConfig()


@dataclass(frozen=True)
class EstimatorTable:
    """The ``[estimator]`` table: the EKF's own settings on this rig (docs/estimator.md).

    ``noise_from_sim`` takes the IMU noise and attachment from the ``[sim]`` tables (the
    simulated rig's figures); every other key is an EKF key, kept in ``keys`` and checked by
    :func:`gyrohost.estimator.config.for_rig`, which names the file and the key at fault.
    """

    noise_from_sim: bool = False
    keys: dict = field(default_factory=dict, metadata={"internal": True, "rest_of_table": True})


@dataclass(frozen=True)
class StartCheckConfig:
    """How far the measured state may be from the scene's initial state when a run connects,
    before anything moves (``gyrohost.run.start_check``); beyond, the run is refused."""

    attitude_rad: float = field(default=0.1, metadata=_spec(lo=0.0, hi=math.pi))
    rate_rad_s: float = field(default=0.05, metadata=_spec(lo=0.0, hi=100.0))
    length_m: float = field(default=0.005, metadata=_spec(lo=0.0, hi=10.0))
    wheel_speed_rad_s: float = field(default=1.0, metadata=_spec(lo=0.0, hi=1000.0))


LOOP_RATE_HZ = 100.0
"""The run loop's tick rate (``gyrohost.run.settings.RunSettings.rate_hz``), Hz: the servos get
their goals at every tick."""


@dataclass(frozen=True)
class RunTable:
    """The ``[run]`` table: limits of a run on this rig (``gyrohost.run.settings.RunSettings``
    takes its defaults from here). Beyond a limit the run ends in the safe state, exit status 1."""

    max_tilt_rad: float = field(
        default=math.inf, metadata=_spec(lo=1e-3, hi=math.pi, doc="absent = unchecked")
    )
    imu_silence_s: float = field(default=0.5, metadata=_spec(lo=0.01, hi=10.0))
    wheel_silence_s: float = field(default=0.5, metadata=_spec(lo=0.01, hi=10.0))
    wheel_speed_margin_rad_s: float = field(default=15.0, metadata=_spec(lo=0.1, hi=1000.0))
    max_wheel_speed_rad_s: float = field(
        default=150.0, metadata=_spec(lo=0.1, hi=1000.0, doc="largest |spin| a schedule commands")
    )
    max_servo_load: float = field(default=0.95, metadata=_spec(lo=0.01, hi=1.0))
    spinup_timeout_s: float = field(default=10.0, metadata=_spec(lo=0.1, hi=600.0))
    steady_tolerance_rad_s: float = field(default=1.5, metadata=_spec(lo=0.01, hi=100.0))
    stop_threshold_rad_s: float = field(default=3.0, metadata=_spec(lo=0.01, hi=100.0))
    rampdown_timeout_s: float = field(default=5.0, metadata=_spec(lo=0.1, hi=600.0))

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
    sim: SimConfig = SimConfig()
    estimator: EstimatorTable = EstimatorTable()
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
        offsets, servos = self.sim.truth.servo_zero_offset_rad, self.servos.servo
        if offsets and len(offsets) != len(servos):
            return [
                ("sim.truth.servo_zero_offset_rad", f"has {len(offsets)} values for "
                 f"{len(servos)} [[servos.servo]] entries (give one per servo, or none)")
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
        return self._resolve_scene("scene", self.scene)

    @property
    def truth_scene_path(self) -> Path:
        """Scene the simulated rig's truth runs: ``[sim.truth] scene``, resolved as ``scene``
        is, else :attr:`scene_path` (truth and model share the scene).

        Raises
        ------
        ConfigError
            The truth's ``scene`` names no file and no shipped scene.
        """
        if not self.sim.truth.scene:
            return self.scene_path
        return self._resolve_scene("sim.truth.scene", self.sim.truth.scene)

    def _resolve_scene(self, key: str, value: str) -> Path:
        try:
            return resolve("scene", value, self.base_dir)
        except ResourceError as exc:
            raise ConfigError(f"{self.source}: key '{key}': {exc}") from None


def with_truth_scene(config: RigConfig, scene: str | Path) -> RigConfig:
    """``config`` with ``[sim.truth] scene`` set to the file ``scene`` (an absolute path, as
    ``--truth-scene`` gives it: it no longer depends on the configuration's folder)."""
    truth = replace(config.sim.truth, scene=str(Path(scene).resolve()))
    return replace(config, sim=replace(config.sim, truth=truth))


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


def load_with_scenes(path, overlays=(), scene=None, truth_scene=None) -> RigConfig:
    """:func:`load_rig_config` with the host's scene and the simulated truth's replaced where
    given (a file or a shipped name, as ``--scene`` and ``--truth-scene`` take them).

    Raises
    ------
    ConfigError, ResourceError
        As :func:`load_rig_config`; a scene that is neither a file nor a shipped name.
    """
    config = load_rig_config(path, overlays)
    if scene is not None:
        config = replace(config, scene=str(resolve("scene", scene)))
    if truth_scene is not None:
        config = with_truth_scene(config, resolve("scene", truth_scene))
    return config


def rig_config_from_dict(data: dict, source: str = "<dict>") -> RigConfig:
    """Build a :class:`RigConfig` from parsed TOML ``data``; ``source`` names it in errors."""
    return replace(_build(RigConfig, data, "", source), source=source)


def _build(cls: type, table: object, where: str, source: str):
    if not isinstance(table, dict):
        raise ConfigError(f"{source}: key '{where.rstrip('.') or '<root>'}' must be a table")
    hints = typing.get_type_hints(cls)
    known = {f.name: f for f in fields(cls) if not f.metadata.get("internal")}
    rest = [f.name for f in fields(cls) if f.metadata.get("rest_of_table")]
    for key in table:
        if key not in known and not rest:
            raise ConfigError(
                f"{source}: unknown key '{where}{key}' (known here: {', '.join(sorted(known))})"
            )
    values = {}
    for name, f in known.items():
        key = f"{where}{name}"
        if name in table:
            values[name] = _convert(hints[name], table[name], key, source)
            _check_range(f.metadata, values[name], key, source)
        elif f.default is MISSING and f.default_factory is MISSING:
            raise ConfigError(f"{source}: missing required key '{key}'")
    if rest:  # keys another module checks (it knows their meaning)
        values[rest[0]] = {k: v for k, v in table.items() if k not in known}
    obj = cls(**values)
    for sub, message in getattr(obj, "problems", lambda: [])():
        raise ConfigError(f"{source}: key '{where}{sub}': {message}")
    return obj


def _convert(hint, value, key: str, source: str):
    origin = typing.get_origin(hint)
    if is_dataclass(hint):
        return _build(hint, value, key + ".", source)
    if origin is tuple:
        return _convert_tuple(typing.get_args(hint), value, key, source)
    if hint is float:
        if isinstance(value, int | float) and not isinstance(value, bool):
            if not math.isfinite(value):
                raise ConfigError(f"{source}: key '{key}' must be finite, got {value}")
            return float(value)
    elif hint in (int, str, bool):
        if isinstance(value, hint) and not (hint is int and isinstance(value, bool)):
            return value
    else:  # pragma: no cover - a programming error in this module, not a user error
        raise TypeError(f"unsupported field type {hint} for {key}")
    raise ConfigError(
        f"{source}: key '{key}' must be {_type_name(hint)}, got {type(value).__name__} {value!r}"
    )


def _convert_tuple(args: tuple, value, key: str, source: str) -> tuple:
    if not isinstance(value, list):
        raise ConfigError(f"{source}: key '{key}' must be an array, got {type(value).__name__}")
    variadic = len(args) == 2 and args[1] is Ellipsis
    if not variadic and len(value) != len(args):
        raise ConfigError(f"{source}: key '{key}' must have {len(args)} elements, got {len(value)}")
    item_types = [args[0]] * len(value) if variadic else list(args)
    return tuple(
        _convert(t, v, f"{key}[{i}]", source)
        for i, (t, v) in enumerate(zip(item_types, value, strict=True))
    )


def _check_range(meta: typing.Mapping, value, key: str, source: str) -> None:
    items = value if isinstance(value, tuple) else (value,)
    for item in items:
        if is_dataclass(item):
            continue
        if meta.get("choices") is not None and item not in meta["choices"]:
            raise ConfigError(
                f"{source}: key '{key}' is {item!r}, must be one of {list(meta['choices'])}"
            )
        if meta.get("min") is not None and item < meta["min"]:
            raise ConfigError(f"{source}: key '{key}' is {item}, below the minimum {meta['min']}")
        if meta.get("max") is not None and item > meta["max"]:
            raise ConfigError(f"{source}: key '{key}' is {item}, above the maximum {meta['max']}")


def _type_name(hint) -> str:
    names = {float: "a number", int: "an integer", str: "a string", bool: "true or false"}
    return names.get(hint, str(hint))


__all__ = [
    "EMULATED_PORT",
    "MX_POSITION_LIMIT",
    "ConfigError",
    "EstimatorTable",
    "ImuConfig",
    "ImuEmuConfig",
    "RigConfig",
    "RunTable",
    "ServoBusConfig",
    "ServoConfig",
    "ServoEmuConfig",
    "SimConfig",
    "StartCheckConfig",
    "StreamFaultConfig",
    "TruthConfig",
    "WHEEL_KINDS",
    "WheelEmuConfig",
    "WheelboardConfig",
    "load_rig_config",
    "load_with_scenes",
    "rig_config_from_dict",
    "with_truth_scene",
]
