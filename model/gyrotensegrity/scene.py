"""Scene files (TOML): parsing and validation into a resolved :class:`Scene`.

Every error is a :class:`SceneError` naming the source and the key at fault, e.g.
``dbar.toml: bars[2].nodes[1]: unknown node 'n9'``. The format is documented in
``docs/scene-format.md``.
"""

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import SceneError
from .piecewise import PiecewiseLinear, constant
from .textfile import read_toml

INTEGRATORS = ("rk4", "rk4-projected", "dop853", "rk45", "radau", "bdf")
MIN_FRAME_SINE = 1e-6
"""Smallest sine of the angle between an attitude frame's two pairs at the start: below it the
y axis is the round-off of a difference of nearly parallel vectors."""


@dataclass(frozen=True)
class WheelSpec:
    """A wheel on a bar. ``mode`` is ``"torque"`` (spin in the state, motor torque as the input,
    ``spin0`` the initial spin) or ``"speed"`` (spin prescribed by ``speed``, the input).
    ``J3``, ``J1`` (kg m^2): axial and transverse inertia given directly (identified), overriding
    the disc's formulas; ``None``: from mass, radius and thickness."""

    mass: float
    radius: float
    thickness: float
    mode: str
    spin0: float
    speed: PiecewiseLinear | None
    torque: PiecewiseLinear | None
    J3: float | None = None
    J1: float | None = None


@dataclass(frozen=True)
class BarSpec:
    """A bar; ``inertia`` (kg m^2): its transverse inertia about its centre given directly
    (identified), overriding the uniform bar's ``mass l^2 / 12``; ``None``: the formula."""

    name: str
    start: str
    end: str
    mass: float
    wheel: WheelSpec | None
    inertia: float | None = None


@dataclass(frozen=True)
class StringSpec:
    name: str
    start: str
    end: str
    stiffness: float
    damping: float
    rest_length: PiecewiseLinear


@dataclass(frozen=True)
class SimulationSettings:
    """Defaults for a run; the command line overrides them."""

    integrator: str = "dop853"
    dt: float = 1e-3
    rtol: float = 1e-10
    atol: float = 1e-12
    sample_dt: float = 0.01
    constraint_tolerance: float = 1e-3


@dataclass(frozen=True)
class RigFidelitySpec:
    """The rig-fidelity option (``[rig_fidelity]``, docs/rig-fidelity.md): ``joints`` "ball"
    (the paper's) or "hinge"; ``stator_inertia`` kg m^2, the axial inertia of a bar that carries
    a wheel's stator; ``motor_reaction``: the motor torque also acts, reversed, on that bar."""

    joints: str = "ball"
    stator_inertia: float = 0.0
    motor_reaction: bool = False


@dataclass(frozen=True)
class Scene:
    """A validated scene. Node positions and velocities are (3, n_scene) arrays in m and m/s."""

    name: str
    source: str
    duration: float
    gravity: np.ndarray
    node_names: list[str]
    positions: np.ndarray
    velocities: np.ndarray
    bars: list[BarSpec]
    strings: list[StringSpec]
    fixed: list[str] = field(default_factory=list)
    point_masses: dict[str, float] = field(default_factory=dict)
    forces: dict[str, np.ndarray] = field(default_factory=dict)
    simulation: SimulationSettings = field(default_factory=SimulationSettings)
    rig: RigFidelitySpec | None = None
    attitude_frame: tuple[str, str, str, str] | None = None
    """The body frame's nodes (``[attitude] frame``, :mod:`gyrotensegrity.attitude`), or None."""

    def node_index(self, name: str) -> int:
        return self.node_names.index(name)

    def jointed_bars(self) -> set[int]:
        """Indices of the bars that share a node with another bar (where a hinge can pass a
        torque about a bar's axis on to the structure)."""
        count: dict[str, int] = {}
        for bar in self.bars:
            for name in (bar.start, bar.end):
                count[name] = count.get(name, 0) + 1
        return {i for i, b in enumerate(self.bars) if count[b.start] > 1 or count[b.end] > 1}

    def to_dict(self) -> dict:
        """The resolved scene as plain JSON-able data (schedules as {t, value})."""

        def sched(s):
            return None if s is None else s.to_dict()

        return {
            "name": self.name,
            "source": self.source,
            "duration": self.duration,
            "gravity": self.gravity.tolist(),
            "nodes": {n: self.positions[:, i].tolist() for i, n in enumerate(self.node_names)},
            "velocities": {
                n: self.velocities[:, i].tolist() for i, n in enumerate(self.node_names)
            },
            "bars": [
                {
                    "name": b.name,
                    "nodes": [b.start, b.end],
                    "mass": b.mass,
                    "inertia": b.inertia,
                    "wheel": None
                    if b.wheel is None
                    else {
                        "mass": b.wheel.mass,
                        "radius": b.wheel.radius,
                        "thickness": b.wheel.thickness,
                        "J3": b.wheel.J3,
                        "J1": b.wheel.J1,
                        "mode": b.wheel.mode,
                        "spin0": b.wheel.spin0,
                        "speed": sched(b.wheel.speed),
                        "torque": sched(b.wheel.torque),
                    },
                }
                for b in self.bars
            ],
            "strings": [
                {
                    "name": s.name,
                    "nodes": [s.start, s.end],
                    "stiffness": s.stiffness,
                    "damping": s.damping,
                    "rest_length": sched(s.rest_length),
                }
                for s in self.strings
            ],
            "fixed": list(self.fixed),
            "point_masses": dict(self.point_masses),
            "forces": {k: v.tolist() for k, v in self.forces.items()},
            "simulation": self.simulation.__dict__.copy(),
            "rig_fidelity": None if self.rig is None else self.rig.__dict__.copy(),
            "attitude": None
            if self.attitude_frame is None
            else {"frame": list(self.attitude_frame)},
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict())


def load_scene(path) -> Scene:
    """Read and validate a TOML scene file.

    Raises
    ------
    SceneError
        If the file cannot be read or parsed, or any key is missing, unknown or invalid.
    """
    return scene_from_dict(read_toml(path, SceneError), source=Path(path).name)


def scene_from_dict(data: dict, source: str = "<scene>") -> Scene:
    """Validate a scene given as a dictionary (the parsed TOML)."""
    return _Parser(source).scene(data)


class _Parser:
    """Validation with the key path carried along for the error messages."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, key: str, what: str):
        raise SceneError(f"{self.source}: {key}: {what}")

    # -- primitives ---------------------------------------------------------------------------
    def table(self, value, key: str, allowed: tuple[str, ...], required=()) -> dict:
        if not isinstance(value, dict):
            self.fail(key, f"must be a table, got {type(value).__name__}")
        for k in value:
            if k not in allowed:
                self.fail(
                    f"{key}.{k}" if key else k, f"unknown key (allowed: {', '.join(allowed)})"
                )
        for k in required:
            if k not in value:
                self.fail(f"{key}.{k}" if key else k, "missing")
        return value

    def number(self, value, key: str, minimum=None, positive=False) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            self.fail(key, f"must be a number, got {type(value).__name__}")
        x = float(value)
        if not math.isfinite(x):
            self.fail(key, f"must be finite, got {x}")
        if positive and x <= 0.0:
            self.fail(key, f"must be positive, got {x}")
        if minimum is not None and x < minimum:
            self.fail(key, f"must be >= {minimum}, got {x}")
        return x

    def vector3(self, value, key: str) -> np.ndarray:
        if not isinstance(value, list) or len(value) != 3:
            self.fail(key, "must be a list of 3 numbers")
        return np.array([self.number(v, f"{key}[{i}]") for i, v in enumerate(value)])

    def name_list(self, value, key: str, known: list[str], length=None) -> list[str]:
        if not isinstance(value, list) or (length is not None and len(value) != length):
            self.fail(key, f"must be a list of {length or 'some'} node names")
        for i, v in enumerate(value):
            self.node_ref(v, f"{key}[{i}]", known)
        return list(value)

    def node_ref(self, value, key: str, known: list[str]) -> str:
        if not isinstance(value, str):
            self.fail(key, "must be a node name (string)")
        if value not in known:
            self.fail(key, f"unknown node '{value}'")
        return value

    def schedule(self, value, key: str, minimum=None, positive=False) -> PiecewiseLinear:
        """A number (held constant) or a table {t = [...], value = [...]}."""
        if not isinstance(value, dict):
            return constant(self.number(value, key, minimum, positive))
        self.table(value, key, ("t", "value"), required=("t", "value"))
        t, v = value["t"], value["value"]
        if not isinstance(t, list) or not isinstance(v, list) or len(t) != len(v) or not t:
            self.fail(key, "t and value must be non-empty lists of the same length")
        ts = np.array([self.number(x, f"{key}.t[{i}]") for i, x in enumerate(t)])
        vs = np.array(
            [self.number(x, f"{key}.value[{i}]", minimum, positive) for i, x in enumerate(v)]
        )
        bad = np.flatnonzero(np.diff(ts) <= 0.0)
        if bad.size:
            i = int(bad[0]) + 1
            self.fail(f"{key}.t[{i}]", f"times must increase strictly ({ts[i - 1]} then {ts[i]})")
        return PiecewiseLinear(ts, vs)

    # -- sections -----------------------------------------------------------------------------
    def scene(self, data: dict) -> Scene:
        top = (
            "scene",
            "nodes",
            "velocities",
            "bars",
            "strings",
            "constraints",
            "point_masses",
            "forces",
            "simulation",
            "rig_fidelity",
            "attitude",
        )
        self.table(data, "", top, required=("scene", "nodes"))
        head = self.table(data["scene"], "scene", ("name", "duration", "gravity"))
        name = head.get("name", Path(self.source).stem)
        if not isinstance(name, str):
            self.fail("scene.name", "must be a string")
        duration = self.number(head.get("duration", 1.0), "scene.duration", positive=True)
        gravity = self.vector3(head.get("gravity", [0.0, 0.0, 0.0]), "scene.gravity")

        nodes = self.table(data["nodes"], "nodes", tuple(data["nodes"]))
        if not nodes:
            self.fail("nodes", "no nodes given")
        names = list(nodes)
        positions = np.column_stack([self.vector3(nodes[n], f"nodes.{n}") for n in names])
        velocities = np.zeros_like(positions)
        vel = self.table(data.get("velocities", {}), "velocities", tuple(names))
        for n, v in vel.items():
            velocities[:, names.index(n)] = self.vector3(v, f"velocities.{n}")

        bars = self.bars(data.get("bars", []), names, positions)
        strings = self.strings(data.get("strings", []), names, positions)
        cons = self.table(data.get("constraints", {}), "constraints", ("fixed",))
        fixed = self.name_list(cons.get("fixed", []), "constraints.fixed", names)
        if len(set(fixed)) != len(fixed):
            self.fail("constraints.fixed", "a node is listed twice")
        masses = self.point_masses(data.get("point_masses", {}), names, bars)
        forces = self.forces(data.get("forces", []), names)
        sim = self.simulation(data.get("simulation", {}))
        rig = self.rig_fidelity(data["rig_fidelity"]) if "rig_fidelity" in data else None
        frame = self.attitude(data["attitude"], names, positions) if "attitude" in data else None
        self.check_supported(names, bars, strings, fixed, masses)
        return Scene(
            name=name,
            source=self.source,
            duration=duration,
            gravity=gravity,
            node_names=names,
            positions=positions,
            velocities=velocities,
            bars=bars,
            strings=strings,
            fixed=fixed,
            point_masses=masses,
            forces=forces,
            simulation=sim,
            rig=rig,
            attitude_frame=frame,
        )

    def member_list(self, value, key: str) -> list:
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            self.fail(key, "must be an array of tables ([[" + key + "]])")
        return value

    def member_name(self, entry: dict, key: str, default: str, seen: set) -> str:
        name = entry.get("name", default)
        if not isinstance(name, str) or not name:
            self.fail(f"{key}.name", "must be a non-empty string")
        if name in seen:
            self.fail(f"{key}.name", f"duplicate name '{name}'")
        seen.add(name)
        return name

    def bars(self, value, names, positions) -> list[BarSpec]:
        out, seen = [], set()
        for i, entry in enumerate(self.member_list(value, "bars")):
            key = f"bars[{i}]"
            allowed = ("name", "nodes", "mass", "inertia", "wheel")
            self.table(entry, key, allowed, required=("nodes", "mass"))
            start, end = self.name_list(entry["nodes"], f"{key}.nodes", names, length=2)
            length = np.linalg.norm(
                positions[:, names.index(end)] - positions[:, names.index(start)]
            )
            if length <= 1e-9:
                self.fail(f"{key}.nodes", f"zero-length bar ({start} and {end} coincide)")
            mass = self.number(entry["mass"], f"{key}.mass", positive=True)
            wheel = self.wheel(entry["wheel"], f"{key}.wheel") if "wheel" in entry else None
            inertia = self.optional_positive(entry, "inertia", key)
            name = self.member_name(entry, key, f"b{i + 1}", seen)
            out.append(BarSpec(name, start, end, mass, wheel, inertia))
        return out

    def wheel(self, value, key: str) -> WheelSpec:
        allowed = ("mass", "radius", "thickness", "J3", "J1", "spin", "torque")
        self.table(value, key, allowed, required=("mass", "radius", "thickness"))
        mass = self.number(value["mass"], f"{key}.mass", positive=True)
        radius = self.number(value["radius"], f"{key}.radius", positive=True)
        thickness = self.number(value["thickness"], f"{key}.thickness", minimum=0.0)
        inertia = {k: self.optional_positive(value, k, key) for k in ("J3", "J1")}
        spin = value.get("spin", 0.0)
        if isinstance(spin, dict):
            if "torque" in value:
                self.fail(
                    f"{key}.torque", "a speed-controlled wheel (spin schedule) takes no torque"
                )
            speed = self.schedule(spin, f"{key}.spin")
            return WheelSpec(mass, radius, thickness, "speed", speed(0.0), speed, None, **inertia)
        spin0 = self.number(spin, f"{key}.spin")
        torque = self.schedule(value.get("torque", 0.0), f"{key}.torque")
        return WheelSpec(mass, radius, thickness, "torque", spin0, None, torque, **inertia)

    def optional_positive(self, table: dict, name: str, key: str) -> float | None:
        """``table[name]`` as a positive finite number, or ``None`` when absent."""
        if name not in table:
            return None
        return self.number(table[name], f"{key}.{name}", positive=True)

    def strings(self, value, names, positions) -> list[StringSpec]:
        out, seen = [], set()
        for i, entry in enumerate(self.member_list(value, "strings")):
            key = f"strings[{i}]"
            allowed = ("name", "nodes", "stiffness", "damping", "rest_length")
            self.table(entry, key, allowed, required=("nodes", "stiffness"))
            start, end = self.name_list(entry["nodes"], f"{key}.nodes", names, length=2)
            if start == end:
                self.fail(f"{key}.nodes", "a string needs two different nodes")
            stiffness = self.number(entry["stiffness"], f"{key}.stiffness", minimum=0.0)
            damping = self.number(entry.get("damping", 0.0), f"{key}.damping", minimum=0.0)
            length = np.linalg.norm(
                positions[:, names.index(end)] - positions[:, names.index(start)]
            )
            rest = self.schedule(entry.get("rest_length", length), f"{key}.rest_length", 0.0)
            name = self.member_name(entry, key, f"s{i + 1}", seen)
            out.append(StringSpec(name, start, end, stiffness, damping, rest))
        return out

    def point_masses(self, value, names, bars) -> dict[str, float]:
        table = self.table(value, "point_masses", tuple(names))
        bar_nodes = {n for b in bars for n in (b.start, b.end)}
        out = {}
        for n, m in table.items():
            out[n] = self.number(m, f"point_masses.{n}", positive=True)
            if n in bar_nodes:
                self.fail(f"point_masses.{n}", "only string-to-string nodes carry point masses")
        return out

    def forces(self, value, names) -> dict[str, np.ndarray]:
        out = {}
        for i, entry in enumerate(self.member_list(value, "forces")):
            key = f"forces[{i}]"
            self.table(entry, key, ("node", "force"), required=("node", "force"))
            node = self.node_ref(entry["node"], f"{key}.node", names)
            out[node] = out.get(node, np.zeros(3)) + self.vector3(entry["force"], f"{key}.force")
        return out

    def simulation(self, value) -> SimulationSettings:
        fields = tuple(SimulationSettings.__dataclass_fields__)
        table = self.table(value, "simulation", fields)
        kwargs = {}
        for k, v in table.items():
            if k == "integrator":
                if v not in INTEGRATORS:
                    self.fail("simulation.integrator", f"unknown integrator '{v}' ({INTEGRATORS})")
                kwargs[k] = v
            else:
                kwargs[k] = self.number(v, f"simulation.{k}", positive=True)
        return SimulationSettings(**kwargs)

    def rig_fidelity(self, value) -> RigFidelitySpec:
        table = self.table(value, "rig_fidelity", tuple(RigFidelitySpec.__dataclass_fields__))
        joints = table.get("joints", "ball")
        if joints not in ("ball", "hinge"):
            self.fail("rig_fidelity.joints", f"must be 'ball' or 'hinge', got {joints!r}")
        inertia = self.number(
            table.get("stator_inertia", 0.0), "rig_fidelity.stator_inertia", minimum=0.0
        )
        reaction = table.get("motor_reaction", False)
        if not isinstance(reaction, bool):
            self.fail("rig_fidelity.motor_reaction", "must be true or false")
        return RigFidelitySpec(joints, inertia, reaction)

    def attitude(self, value, names, positions) -> tuple[str, str, str, str]:
        """The body frame's nodes: two pairs, each of two nodes apart, not parallel at the start
        (else the frame has no x or no y axis)."""
        table = self.table(value, "attitude", ("frame",), required=("frame",))
        frame = tuple(self.name_list(table["frame"], "attitude.frame", names, length=4))
        ends = positions[:, [names.index(n) for n in frame]]
        axes = ends[:, 1::2] - ends[:, 0::2]
        lengths = np.linalg.norm(axes, axis=0)
        for k, axis in enumerate("xy"):
            if lengths[k] <= 1e-9:
                a, b = frame[2 * k : 2 * k + 2]
                self.fail("attitude.frame", f"the {axis} pair's nodes {a} and {b} coincide")
        sine = np.linalg.norm(np.cross(axes[:, 0], axes[:, 1])) / (lengths[0] * lengths[1])
        if sine < MIN_FRAME_SINE:
            self.fail(
                "attitude.frame",
                f"the pairs {frame[0]}-{frame[1]} and {frame[2]}-{frame[3]} are parallel at the "
                "start (no y axis)",
            )
        return frame

    def check_supported(self, names, bars, strings, fixed, masses):
        """Every node must be a bar end, carry a point mass, or be fixed: else it has no inertia."""
        bar_nodes = {n for b in bars for n in (b.start, b.end)}
        string_nodes = {n for s in strings for n in (s.start, s.end)}
        for n in names:
            if n not in bar_nodes and n not in masses and n not in fixed:
                what = "string-to-string node" if n in string_nodes else "node on no member"
                self.fail(f"nodes.{n}", f"{what} without mass: give it a point mass or fix it")
