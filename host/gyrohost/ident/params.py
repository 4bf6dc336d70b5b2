"""The parameters identification can estimate, and how a parameter vector changes the rig.

Physical parameters are estimated as logarithms of their factor on the configuration's scene
(``theta = 0``: the nominal value, ``theta = 0.1``: about 10 % more), so their sigmas and the
combinations the data cannot separate read as fractions, and a ratio the data determine (say J3
over the bar mass) is a straight line in ``theta``; the IMU and servo parameters are
absolute (rad, rad/s, m/s^2, m, s). A parameter *group* (``--params``) is one of :data:`GROUPS`.
"""

from dataclasses import dataclass, replace

import numpy as np

from gyrohost.config import RigConfig
from gyrohost.ident.groups import FILTER_GROUPS, GROUPS
from gyrotensegrity import Scene

from .errors import ParamsError

STRING_STEP = 0.1
"""Finite-difference step of the strings' stiffness and damping (log factor): their effect is
small beside the jumps of the cost where a string goes slack a step earlier or later, so the
Jacobian takes their secant over +-10 %."""
LATENCY_STEP_S = 2e-3
"""Finite-difference step of the IMU's latency, s: a fifth of the 10 ms sample period; the
predicted samples move smoothly with it (interpolated between the model's steps, or fused at
their own time by the filter)."""
OUTPUT_GROUPS = ("mounting", "gyro-bias", "accel-bias")
"""Groups that act on the sensor's outputs only: changing them needs no new simulation."""


@dataclass(frozen=True)
class Param:
    """One estimated number.

    Attributes
    ----------
    name : str
        e.g. ``J3``, ``J3[b12]``, ``mounting.roll``, ``servo_offset[s13]``.
    group : str
        Its entry of :data:`GROUPS`.
    relative : bool
        ``True``: the logarithm of a factor on ``nominal``; ``False``: an absolute value in
        ``unit`` (``nominal`` plus ``theta``).
    nominal : float
        The configuration's value (physical unit), reported beside the estimate.
    unit : str
    lower, upper : float
        Bounds of ``theta``.
    step : float
        Finite-difference step of ``theta`` for the Jacobian: wide enough to step over the
        small jumps of the fixed-step simulation where a string goes slack (its damping stops).
    """

    name: str
    group: str
    relative: bool
    nominal: float
    unit: str
    lower: float = -np.inf
    step: float = 3e-2
    upper: float = np.inf

    def value(self, theta: float) -> float:
        """The physical value of ``theta`` (a relative one past the floats: infinite, a trial
        the filter refuses)."""
        if not self.relative:
            return self.nominal + theta
        with np.errstate(over="ignore"):
            return self.nominal * np.exp(theta)


def wheel_J3(scene: Scene) -> dict[str, float]:
    """Axial inertia of each wheel by bar name, kg m^2 (given, else the disc's)."""
    return {
        b.name: b.wheel.J3 if b.wheel.J3 is not None else 0.5 * b.wheel.mass * b.wheel.radius**2
        for b in scene.bars
        if b.wheel is not None
    }


def bar_inertia(scene: Scene) -> dict[str, float]:
    """Transverse inertia of each bar about its centre by name, kg m^2 (given, else m l^2/12)."""
    out = {}
    for b in scene.bars:
        i, j = scene.node_index(b.start), scene.node_index(b.end)
        length = np.linalg.norm(scene.positions[:, j] - scene.positions[:, i])
        out[b.name] = b.inertia if b.inertia is not None else b.mass * length**2 / 12.0
    return out


def bias_name(group: str, axis: str, recording: int, recordings: int) -> str:
    """The name of a bias parameter: ``gyro_bias.x``, or with several recordings each its own
    (a MEMS bias changes from one power-up to the next), ``gyro_bias.x[2]`` for the second."""
    name = f"{group.replace('-', '_')}.{axis}"
    return name if recordings == 1 else f"{name}[{recording + 1}]"


def accel_psd_ceiling(est, config) -> float:
    """The largest node-acceleration noise the likelihood may fit, m^2/s^3: the accelerometer's
    own white noise as a density (``imu_accel_std_m_s2^2 / rate_hz``). Above it the filter's
    prediction of the frame's acceleration is worse than one sample of it, the IMU carries the
    motion alone and the likelihood is flat; there the solver's trust region grew until a
    factor of 1e163 broke the filter and left the other parameters undetermined."""
    return est.imu_accel_std_m_s2**2 / config.imu.rate_hz


def parameters(
    scene: Scene,
    config: RigConfig,
    groups,
    servo_lag_s: float,
    recordings: int = 1,
    est=None,
    by_filter: bool = False,
) -> list[Param]:
    """The :class:`Param` list of ``groups`` (names of :data:`GROUPS`) for this rig;
    ``servo_lag_s``: the nominal lag (s), the start of its fit; ``recordings``: how many
    recordings are fitted (the IMU's biases are one set per recording); ``est``: the
    EstimatorConfig whose IMU latency and noise start ``imu-latency`` and ``process-noise``
    (None: the latency from 0); ``by_filter``: fitted by the filter's likelihood, which alone
    fits :data:`FILTER_GROUPS`.

    Raises
    ------
    ParamsError
        An unknown group, ``J3`` with ``J3-each``, a filter group fitted otherwise, or
        ``process-noise`` where the filter takes no node noise to scale.
    """
    unknown = [g for g in groups if g not in GROUPS]
    if unknown:
        raise ParamsError(f"unknown parameter group(s) {unknown} (known: {', '.join(GROUPS)})")
    if "J3" in groups and "J3-each" in groups:
        raise ParamsError("J3 and J3-each are alternatives: give one")
    if not by_filter and (asked := [g for g in groups if g in FILTER_GROUPS]):
        raise ParamsError(f"{', '.join(asked)}: fitted by the filter's likelihood only "
                          "(--method filter)")  # fmt: skip
    if "process-noise" in groups and est is not None and est.accel_psd_m2_s3 == 0.0:
        raise ParamsError("process-noise scales [estimator] accel_psd_m2_s3, which is 0 here "
                          "(no node noise): give it a value to scale")  # fmt: skip
    J3 = wheel_J3(scene)
    if not J3 and ("J3" in groups or "J3-each" in groups):
        raise ParamsError(f"scene {scene.name} has no wheel: J3 cannot be identified")
    mean = float(np.mean([b.mass for b in scene.bars]))
    out: list[Param] = []
    for g in groups:
        if g == "J3":
            out.append(Param("J3", g, True, float(np.mean(list(J3.values()))), "kg m^2"))
        elif g == "J3-each":
            out += [Param(f"J3[{n}]", g, True, v, "kg m^2") for n, v in J3.items()]
        elif g == "bar-mass":
            out.append(Param("bar_mass", g, True, mean, "kg"))
        elif g == "bar-inertia":
            nominal = float(np.mean(list(bar_inertia(scene).values())))
            out.append(Param("bar_inertia", g, True, nominal, "kg m^2"))
        elif g in ("stiffness", "damping"):
            values = [getattr(s, g) for s in scene.strings]
            out.append(Param(g, g, True, float(np.mean(values)), _UNITS[g], step=STRING_STEP))
        elif g == "mounting":
            rpy = config.imu.mounting_rpy_rad
            out += [
                Param(f"mounting.{a}", g, False, rpy[i], "rad", step=1e-3)
                for i, a in enumerate(_RPY)
            ]
        elif g in ("gyro-bias", "accel-bias"):
            unit = _UNITS[g]
            out += [
                Param(bias_name(g, a, k, recordings), g, False, 0.0, unit, step=1e-3)
                for k in range(recordings)
                for a in "xyz"
            ]
        elif g == "servo-offsets":
            out += [
                Param(f"servo_offset[{s.string}]", g, False, 0.0, "m", step=1e-3)
                for s in config.servos.servo
                if s.string
            ]
        elif g == "imu-latency":
            nominal = 0.0 if est is None else est.imu_latency_s  # latency >= 0
            out.append(Param("imu_latency", g, False, nominal, "s", -nominal, LATENCY_STEP_S))
        elif g == "process-noise":
            nominal, ceiling = est.accel_psd_m2_s3, accel_psd_ceiling(est, config)
            upper = max(np.log(ceiling / nominal), 0.0)  # a nominal above it may stay
            out.append(Param("accel_psd", g, True, nominal, "m^2/s^3", step=0.3, upper=upper))
        else:
            out.append(Param("servo_lag", g, False, servo_lag_s, "s", -servo_lag_s, 5e-3))
    return out


_RPY = ("roll", "pitch", "yaw")
_UNITS = {"stiffness": "N/m", "damping": "N s/m", "gyro-bias": "rad/s", "accel-bias": "m/s^2"}


@dataclass(frozen=True)
class Applied:
    """What a parameter vector means for the rig.

    Attributes
    ----------
    scene : Scene
        The configuration's scene with the physical parameters applied.
    offsets_m : ndarray, shape (n_servos,), m
    servo_lag_s : float, s
    mounting_rpy_rad : ndarray, shape (3,), rad
    gyro_bias_rad_s : ndarray, shape (recordings, 3), rad/s
    accel_bias_m_s2 : ndarray, shape (recordings, 3), m/s^2
    imu_latency_s : float, s
    accel_psd_factor : float
        On the filter's ``accel_psd_m2_s3``.
    """

    scene: Scene
    offsets_m: np.ndarray
    servo_lag_s: float
    mounting_rpy_rad: np.ndarray
    gyro_bias_rad_s: np.ndarray
    accel_bias_m_s2: np.ndarray
    imu_latency_s: float
    accel_psd_factor: float


def apply(
    scene: Scene,
    config: RigConfig,
    params: list[Param],
    theta,
    servo_lag_s,
    recordings: int = 1,
    imu_latency_s: float = 0.0,
) -> Applied:
    """The rig of parameter vector ``theta`` (shape (len(params),)) for ``recordings``
    recordings; groups not estimated keep the configuration's values (biases zero, the lag
    ``servo_lag_s``, the IMU's latency ``imu_latency_s``, the filter's noise)."""
    by = {p.name: (p, float(t)) for p, t in zip(params, theta, strict=True)}

    def factor(name):
        if name not in by:
            return 1.0
        with np.errstate(over="ignore"):  # infinite past the floats: a trial the filter refuses
            return np.exp(by[name][1])

    def absolute(name, default):
        return by[name][0].value(by[name][1]) if name in by else default

    J3, inertia = wheel_J3(scene), bar_inertia(scene)
    bars = []
    for b in scene.bars:
        wheel = b.wheel
        if wheel is not None and ("J3" in by or f"J3[{b.name}]" in by):
            wheel = replace(wheel, J3=J3[b.name] * factor("J3") * factor(f"J3[{b.name}]"))
        mass = b.mass * factor("bar_mass")
        given = b.inertia if "bar_inertia" not in by else inertia[b.name] * factor("bar_inertia")
        bars.append(replace(b, mass=mass, wheel=wheel, inertia=given))
    strings = [
        replace(
            s, stiffness=s.stiffness * factor("stiffness"), damping=s.damping * factor("damping")
        )
        for s in scene.strings
    ]
    servos = [s for s in config.servos.servo if s.string]
    rpy = config.imu.mounting_rpy_rad
    return Applied(
        replace(scene, bars=bars, strings=strings),
        np.array([absolute(f"servo_offset[{s.string}]", 0.0) for s in servos]),
        absolute("servo_lag", servo_lag_s),
        np.array([absolute(f"mounting.{a}", rpy[i]) for i, a in enumerate(_RPY)]),
        *(
            np.array(
                [
                    [absolute(bias_name(g, a, k, recordings), 0.0) for a in "xyz"]
                    for k in range(recordings)
                ]
            )
            for g in ("gyro-bias", "accel-bias")
        ),
        absolute("imu_latency", imu_latency_s),
        factor("accel_psd"),
    )
