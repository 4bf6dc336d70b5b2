"""The simulated rig's configuration: the ``[sim]`` tables of a rig configuration file.

A real rig's configuration (:mod:`gyrohost.config`) keeps these tables as it read them and
never looks inside: only the simulated rig knows its emulators and its truth. They are checked
here, by the same rules and with the same messages (:mod:`gyrohost.configfile`), when the
simulated rig is built from the configuration, before anything starts.
"""

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

from gyrohost.config import IMU_FRAME_NODES, RigConfig
from gyrohost.configfile import build, spec
from gyrohost.errors import ConfigError
from gyrotensegrity import load_scene


@dataclass(frozen=True)
class StreamFaultConfig:
    """Faults applied to the bytes an emulator sends (see ``gyrohost.simrig.faults``)."""

    corrupt_byte_prob: float = field(default=0.0, metadata=spec(lo=0.0, hi=1.0))
    drop_byte_prob: float = field(default=0.0, metadata=spec(lo=0.0, hi=1.0))
    silent: bool = False
    stall_period_s: float = field(default=0.0, metadata=spec(lo=0.0, doc="0 = never"))
    stall_duration_s: float = field(default=0.0, metadata=spec(lo=0.0))
    seed: int = field(default=0, metadata=spec(lo=0))

    def problems(self) -> list[tuple[str, str]]:
        if self.stall_period_s > 0 and self.stall_duration_s >= self.stall_period_s:
            return [("stall_duration_s", "must be shorter than stall_period_s")]
        return []


@dataclass(frozen=True)
class ImuEmuConfig:
    """Simulated BWT61CL: MPU6050-like noise (datasheet densities), bias, temperature."""

    gyro_noise_density_rad_s_rthz: float = field(
        default=math.radians(0.005), metadata=spec(lo=0.0, hi=1.0)
    )
    accel_noise_density_m_s2_rthz: float = field(
        default=400e-6 * 9.80665, metadata=spec(lo=0.0, hi=10.0)
    )
    gyro_bias_std_rad_s: float = field(default=math.radians(0.5), metadata=spec(lo=0.0, hi=1.0))
    accel_bias_std_m_s2: float = field(default=0.05, metadata=spec(lo=0.0, hi=5.0))
    angle_noise_std_rad: float = field(default=math.radians(0.05), metadata=spec(lo=0.0, hi=0.5))
    temperature_degC: float = field(default=25.0, metadata=spec(lo=-40.0, hi=85.0))
    seed: int = field(default=1, metadata=spec(lo=0))
    faults: StreamFaultConfig = StreamFaultConfig()


@dataclass(frozen=True)
class ServoEmuConfig:
    """Simulated MX-12W bus: motor figures and servo-level faults."""

    return_delay_us: int = field(default=20, metadata=spec(lo=0, hi=508))
    no_load_speed_rpm: float = field(default=470.0, metadata=spec(lo=1.0, hi=1000.0))
    stall_torque_N_m: float = field(default=0.2, metadata=spec(lo=1e-3, hi=10.0))
    overload_ids: tuple[int, ...] = field(default=(), metadata=spec(lo=0, hi=252))
    no_reply_ids: tuple[int, ...] = field(default=(), metadata=spec(lo=0, hi=252))
    # a servo at rest stops anywhere within this many steps of its goal (uniform): its shaft
    # is continuous, its encoder reads a count (0.5: within the count its read shows)
    hold_band_steps: float = field(default=0.5, metadata=spec(lo=0.0, hi=10.0))
    seed: int = field(default=3, metadata=spec(lo=0, doc="of the positions where servos stop"))
    faults: StreamFaultConfig = StreamFaultConfig()


WHEEL_KINDS = ("emulator", "simavr")
"""Simulated wheel boards: the Python emulator, or the real firmware ELF in the simavr harness."""


@dataclass(frozen=True)
class WheelEmuConfig:
    """Simulated wheel board: which one, speed response of the motors, ripple, stream faults.

    ``kind = "simavr"`` runs the real firmware in the FIL harness (docs/fil.md); the emulator's
    motor, EEPROM and fault keys then do not apply, ``spin_sign`` does for both kinds.
    """

    time_constant_s: float = field(default=0.05, metadata=spec(lo=1e-4, hi=10.0))
    coast_time_constant_s: float = field(default=5.0, metadata=spec(lo=1e-3, hi=1000.0))
    ripple_fraction: float = field(default=0.0, metadata=spec(lo=0.0, hi=0.5))
    ripple_per_rev: int = field(default=1, metadata=spec(lo=1, hi=100))
    speed_error_std_rad_s: float = field(
        default=0.01, metadata=spec(lo=0.0, hi=10.0, doc="the speed loop's error, stationary std")
    )
    seed: int = field(default=2, metadata=spec(lo=0, doc="of the speed error"))
    blank_eeprom: bool = field(
        default=False, metadata=spec(doc="the emulator boots as a new board, uncalibrated")
    )
    faults: StreamFaultConfig = StreamFaultConfig()
    kind: str = field(default="emulator", metadata=spec(choices=WHEEL_KINDS))
    spin_sign: tuple[int, int, int, int] = field(
        default=(1, 1, 1, 1), metadata=spec(choices=(-1, 1), doc="board wheel i -> scene spin")
    )
    simavr_elf: str = field(default="", metadata=spec(doc="'' = $GYROTENS_FIRMWARE_BUILD/avr"))
    simavr_harness: str = field(default="", metadata=spec(doc="'' = $GYROTENS_FIRMWARE_BUILD/sim"))
    simavr_options: tuple[str, ...] = ()

    def problems(self) -> list[tuple[str, str]]:
        if self.kind == "simavr" and self.faults != StreamFaultConfig():
            return [("faults", "stream faults need kind = 'emulator' (simavr's pty is direct)")]
        return []


@dataclass(frozen=True)
class TruthConfig:
    """The rig's truth model: step, IMU attachment and deliberate model mismatch.

    ``scene``, ``imu_rotation_deg`` and ``servo_zero_offset_rad`` make the truth differ from what
    the host knows (its scene, ``imu.mounting_rpy_rad``, the servos' ``zero_position``), as a real
    rig differs from its model; ``gyrohost.simrig.truth`` applies them.
    """

    dt_s: float = field(default=0.005, metadata=spec(lo=1e-4, hi=0.02))
    imu_frame_nodes: tuple[str, str, str] = IMU_FRAME_NODES
    imu_gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.80665)
    wheel_inertia_scale: float = field(default=1.0, metadata=spec(lo=0.1, hi=10.0))
    servo_lag_s: float = field(default=0.0, metadata=spec(lo=0.0, hi=10.0))
    imu_latency_s: float = field(default=0.0, metadata=spec(lo=0.0, hi=1.0))
    scene: str = field(default="", metadata=spec(doc="scene the truth runs; '' = the config's"))
    imu_rotation_deg: tuple[float, float, float] = field(
        default=(0.0, 0.0, 0.0), metadata=spec(lo=-180.0, hi=180.0)
    )
    servo_zero_offset_rad: tuple[float, ...] = field(
        default=(), metadata=spec(lo=-math.pi, hi=math.pi, doc="per [[servos.servo]]; [] = 0")
    )


@dataclass(frozen=True)
class SimConfig:
    """The ``[sim]`` tables: the simulated devices (used only for ports set to ``"emulator"``)
    and the truth they measure."""

    imu: ImuEmuConfig = ImuEmuConfig()
    servos: ServoEmuConfig = ServoEmuConfig()
    wheels: WheelEmuConfig = WheelEmuConfig()
    truth: TruthConfig = TruthConfig()


def sim_config(rig: RigConfig) -> SimConfig:
    """The simulated rig's settings in ``rig``'s ``[sim]`` tables (defaults where absent).

    Raises
    ------
    ConfigError
        A key is unknown, mistyped or out of range, or the truth's servo offsets do not match
        the rig's servos (naming the file and the key).
    """
    sim = build(SimConfig, rig.sim, "sim.", rig.source)
    offsets, servos = sim.truth.servo_zero_offset_rad, rig.servos.servo
    if offsets and len(offsets) != len(servos):
        raise ConfigError(
            f"{rig.source}: key 'sim.truth.servo_zero_offset_rad': has {len(offsets)} values for "
            f"{len(servos)} [[servos.servo]] entries (give one per servo, or none)"
        )
    return sim


def truth_scene_path(rig: RigConfig, model_path: Path | None = None) -> Path:
    """Scene the simulated rig's truth runs: ``[sim.truth] scene``, resolved as the rig's
    ``scene`` is, else the model's (``model_path``, default the rig's scene: truth and model
    share it).

    Raises
    ------
    ConfigError
        The truth's ``scene`` names no file and no shipped scene.
    """
    scene = sim_config(rig).truth.scene
    if scene:
        return rig.resolve_scene("sim.truth.scene", scene)
    return rig.scene_path if model_path is None else model_path


def with_truth_scene(rig: RigConfig, scene: str | Path) -> RigConfig:
    """``rig`` with ``[sim.truth] scene`` set to the file ``scene`` (an absolute path, as
    ``--truth-scene`` gives it: it no longer depends on the configuration's folder), and the
    estimator's keys that scene's physics fixes as a rig's hardware would
    (:func:`hardware_keys`) where the rig's ``[estimator]`` table does not set them.

    Raises
    ------
    SceneError
        ``scene`` is no scene file.
    """
    rig = with_sim_keys(rig, "truth", scene=str(Path(scene).resolve()))
    return replace(rig, estimator={**hardware_keys(load_scene(scene)), **rig.estimator})


def hardware_keys(scene) -> dict:
    """Estimator keys a truth ``scene`` fixes: ``wheel_reaction = "body"`` where its hinges carry
    the motors' reaction (``[rig_fidelity] joints = "hinge"`` and ``motor_reaction``), as the
    real D-bar's do (docs/estimator.md); none otherwise."""
    spec = scene.rig
    hinged = spec is not None and spec.joints == "hinge" and spec.motor_reaction
    return {"wheel_reaction": "body"} if hinged else {}


def with_sim_keys(rig: RigConfig, table: str, **keys) -> RigConfig:
    """``rig`` with ``keys`` set in its ``[sim.<table>]`` table (checked when read)."""
    return replace(rig, sim={**rig.sim, table: {**rig.sim.get(table, {}), **keys}})
