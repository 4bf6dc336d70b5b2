"""The sweep spec (TOML, docs/sweeps.md): base scene, axes, sampling, integrator, records, plots.

:func:`load_spec` reads and checks a spec; every mistake is a :class:`SpecError` naming the file
and the key (``dbar-turn.toml: axes[1].key: 'bars.*.wheel.spn': no key 'spn' in bars.*.wheel``).
:func:`case_count` says how many cases a spec has without making them, :func:`cases` expands the
axes into the cases one at a time (grid or Latin hypercube) and :func:`apply` writes one case's
values into a copy of the base scene's data by dotted key.
"""

import copy
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gyrohost.control.attitude import PLANE_NODES
from gyrohost.resources import ResourceError, resolve
from gyrotensegrity import SceneError, scene_from_dict
from gyrotensegrity.integrators import NAMES
from gyrotensegrity.runfile import RUN_KEYS
from gyrotensegrity.textfile import read_toml

from .errors import SpecError

OPS = ("set", "scale", "magnitude", "stretch")
"""How an axis value ``v`` changes each number ``x`` at its key: ``set`` x = v, ``scale``
x = v x, ``magnitude`` x = sign(x) v (keeps a spin pattern), ``stretch`` a list times
v / its last element (a schedule's times end at v)."""
METRICS = ("final_tilt_deg", "peak_node_z_m", "energy_drift", "momentum_drift", "wall_s")
"""Recorded quantities computed by the sweep (:func:`gyrohost.sweep.case.run_case`); any other
name is a run-file quantity (:data:`NUMERIC_RUN_KEYS`) with an optional ``:reducer``."""
NUMERIC_RUN_KEYS = tuple(k for k in RUN_KEYS if k not in ("node_names", "scene", "meta"))
REDUCERS = ("final", "max", "min", "mean", "maxabs")
INTEGRATOR_KEYS = (
    "integrator",
    "dt",
    "rtol",
    "atol",
    "sample_dt",
    "duration",
    "constraint_tolerance",
)
SAMPLINGS = ("grid", "lhs")


@dataclass(frozen=True)
class Linear(Sequence):
    """``num`` evenly spaced values from ``start`` to ``stop``, both included: the values of
    ``numpy.linspace``, bit for bit (case ids hash them), each computed when asked for, so a
    ``num`` mistyped a thousand times too large costs nothing before the sweep's size is
    checked (:func:`case_count`)."""

    start: float
    stop: float
    num: int

    def __len__(self) -> int:
        return self.num

    def __getitem__(self, k):
        if isinstance(k, slice):
            return tuple(self[i] for i in range(*k.indices(self.num)))
        if k < 0:
            k += self.num
        if not 0 <= k < self.num:
            raise IndexError(f"value {k} of {self.num}")
        if k == self.num - 1 and self.num > 1:
            return self.stop
        step = (self.stop - self.start) / max(self.num - 1, 1)
        return float(k * step + self.start) if step != 0.0 else self.start


@dataclass(frozen=True)
class Axis:
    """One swept parameter: ``values`` (a tuple, a :class:`Linear` range, or for a Latin
    hypercube its interval) written at the dotted scene ``key`` by ``op``."""

    name: str
    key: str
    op: str
    values: Sequence[float]


@dataclass
class Spec:
    """A checked sweep spec.

    Attributes
    ----------
    path : Path
        The spec file.
    name : str
    scene_path : Path
        The base scene file (a path relative to the spec, else a shipped scene name).
    scene : dict
        The base scene's data (parsed TOML), never changed.
    axes : list of Axis
    sampling : {"grid", "lhs"}
    n_cases : int
        Latin hypercube only: the number of cases.
    seed : int
    integrator : dict
        Keyword arguments of :func:`gyrotensegrity.simulate` (scene defaults where missing).
    record : list of str
        Metrics (:data:`METRICS`) and run-file quantities (``name`` or ``name:reducer``).
    heatmap, contour : str or None, float or None
        The quantity shown over two axes and a level drawn on it.
    pareto : dict or None
        ``cost``, ``goal`` (names of axes or records) and ``target`` (goal is brought to it) or
        ``sense`` ("min"/"max").
    """

    path: Path
    name: str
    scene_path: Path
    scene: dict
    axes: list
    sampling: str = "grid"
    n_cases: int = 0
    seed: int = 0
    integrator: dict = field(default_factory=dict)
    record: list = field(default_factory=list)
    heatmap: str | None = None
    contour: float | None = None
    pareto: dict | None = None


def load_spec(path) -> Spec:
    """Read and check the sweep spec at ``path`` (a file, else the name of a shipped spec).

    Raises
    ------
    SpecError
        Unreadable file, invalid TOML, an unknown or missing key, a wrong value, an axis key
        that is not in the base scene; the message names the file and the key.
    """
    path = _spec_file(path)
    data = read_toml(path, SpecError)
    where = path.name

    def fail(key, what):
        raise SpecError(f"{where}: {key}: {what}")

    _known(data, ("sweep", "axes", "integrator", "plots", "pareto"), "", fail)
    sweep = _table(data, "sweep", fail, required=True)
    _known(sweep, ("name", "scene", "sampling", "cases", "seed", "record"), "sweep.", fail)
    if "scene" not in sweep:
        fail("sweep.scene", "missing (a scene file or a shipped scene name)")
    try:
        scene_path = resolve("scene", _text(sweep["scene"], "sweep.scene", fail), base=path.parent)
    except ResourceError as exc:
        fail("sweep.scene", str(exc))
    scene = read_toml(scene_path, SpecError)
    try:
        scene_from_dict(scene, source=scene_path.name)
    except SceneError as exc:
        fail("sweep.scene", f"the base scene is invalid: {exc}")
    spec = Spec(path, str(sweep.get("name", path.stem)), scene_path, scene, [])
    spec.sampling = sweep.get("sampling", "grid")
    if spec.sampling not in SAMPLINGS:
        fail("sweep.sampling", f"{spec.sampling!r}: one of {', '.join(SAMPLINGS)}")
    if spec.sampling == "lhs":
        spec.n_cases = _count(sweep.get("cases"), "sweep.cases", fail)
    spec.seed = int(_number(sweep.get("seed", 0), "sweep.seed", fail))
    axes = data.get("axes")
    if not isinstance(axes, list) or not axes:
        fail("axes", "missing: at least one [[axes]] table")
    spec.axes = [_axis(a, f"axes[{k}]", scene, spec.sampling, fail) for k, a in enumerate(axes)]
    names = [a.name for a in spec.axes]
    if len(set(names)) < len(names):
        fail("axes", f"axis names repeat: {names}")
    integ = _table(data, "integrator", fail)
    _known(integ, INTEGRATOR_KEYS, "integrator.", fail)
    if integ.get("integrator", NAMES[0]) not in NAMES:
        fail("integrator.integrator", f"{integ['integrator']!r}: one of {', '.join(NAMES)}")
    spec.integrator = {
        k: (v if k == "integrator" else _number(v, f"integrator.{k}", fail))
        for k, v in integ.items()
    }
    record = sweep.get("record", ["final_tilt_deg", "wall_s"])
    if not isinstance(record, list) or not record:
        fail("sweep.record", "a list of quantity names")
    spec.record = [_quantity(q, f"sweep.record[{k}]", fail) for k, q in enumerate(record)]
    missing = [n for n in PLANE_NODES if n not in scene.get("nodes", {})]
    if "final_tilt_deg" in spec.record and missing:
        fail("sweep.record", f"final_tilt_deg needs the D-bar's plane nodes (no {missing} in "
             f"{scene_path.name})")  # fmt: skip
    columns = names + spec.record
    plots = _table(data, "plots", fail)
    _known(plots, ("heatmap", "contour"), "plots.", fail)
    spec.heatmap = _column(plots.get("heatmap", spec.record[0]), "plots.heatmap", columns, fail)
    if "contour" in plots:
        spec.contour = _number(plots["contour"], "plots.contour", fail)
    if "pareto" in data:
        spec.pareto = _pareto(data["pareto"], columns, fail)
    return spec


def _spec_file(path) -> Path:
    if Path(path).is_file() or "/" in str(path):
        return Path(path)  # a missing path: read_toml names it
    return shipped_spec(str(path))


def shipped_spec(name: str) -> Path:
    """The spec shipped as package data (``gyrohost/sweeps/<name>.toml``)."""
    from importlib import resources

    folder = Path(str(resources.files("gyrohost").joinpath("sweeps")))
    found = folder / f"{name.removesuffix('.toml')}.toml"
    if not found.is_file():
        names = ", ".join(sorted(p.stem for p in folder.glob("*.toml")))
        raise SpecError(f"{name}: no such file and no shipped sweep spec (shipped: {names})")
    return found


def _known(table, allowed, prefix, fail):
    for key in table:
        if key not in allowed:
            fail(f"{prefix}{key}", f"unknown key (known: {', '.join(allowed)})")


def _table(data, key, fail, required=False) -> dict:
    value = data.get(key, None)
    if value is None and not required:
        return {}
    if not isinstance(value, dict):
        fail(key, "missing table" if value is None else "must be a table")
    return value


def _text(value, key, fail) -> str:
    if not isinstance(value, str) or not value:
        fail(key, f"{value!r}: must be a non-empty string")
    return value


def _number(value, key, fail) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        fail(key, f"{value!r}: must be a finite number")
    return value


def _count(value, key, fail) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        fail(key, f"{value!r}: must be a whole number >= 1")
    return value


def _axis(table, key, scene, sampling, fail) -> Axis:
    if not isinstance(table, dict):
        fail(key, "must be a table")
    _known(table, ("name", "key", "op", "values", "range"), f"{key}.", fail)
    dotted = _text(table.get("key"), f"{key}.key", fail)
    name = _text(table.get("name", dotted), f"{key}.name", fail)
    op = table.get("op", "set")
    if op not in OPS:
        fail(f"{key}.op", f"{op!r}: one of {', '.join(OPS)}")
    if ("values" in table) == ("range" in table):
        fail(key, "give either values = [...] or range = { start, stop, num }")
    if "values" in table:
        values = table["values"]
        if not isinstance(values, list) or not values:
            fail(f"{key}.values", "must be a non-empty list")
        values = tuple(_number(v, f"{key}.values[{i}]", fail) for i, v in enumerate(values))
    elif not isinstance(table["range"], dict):
        fail(f"{key}.range", "must be a table { start, stop, num } (num: grid only)")
    else:
        values = _range(table["range"], f"{key}.range", sampling, fail)
    if sampling == "lhs" and "range" not in table:
        fail(key, "Latin hypercube axes are intervals: range = { start, stop }")
    axis = Axis(name, dotted, op, values)
    try:
        apply(scene, [axis], [values[0]])
    except KeyError as exc:
        fail(f"{key}.key", f"{dotted!r}: {exc.args[0]}")
    except (TypeError, ZeroDivisionError):
        fail(f"{key}.op", f"{op!r} cannot change the value at {dotted!r}")
    return axis


def _range(table, key, sampling, fail) -> tuple:
    _known(table, ("start", "stop", "num"), f"{key}.", fail)
    start, stop = (_number(table.get(k), f"{key}.{k}", fail) for k in ("start", "stop"))
    if sampling == "lhs":
        if "num" in table:
            fail(f"{key}.num", "Latin hypercube axes are intervals: no num")
        if not start < stop:
            fail(key, f"start {start} must be below stop {stop}")
        return (float(start), float(stop))
    return Linear(float(start), float(stop), _count(table.get("num"), f"{key}.num", fail))


def _quantity(value, key, fail) -> str:
    name = _text(value, key, fail)
    quantity, _, reducer = name.partition(":")
    if reducer and reducer not in REDUCERS:
        fail(key, f"{name!r}: reducer {reducer!r} is not one of {', '.join(REDUCERS)}")
    if quantity in METRICS and reducer:
        fail(key, f"{name!r}: {quantity} is one number per case (no reducer)")
    if quantity not in METRICS and quantity not in NUMERIC_RUN_KEYS:
        known = ", ".join(METRICS + NUMERIC_RUN_KEYS)
        fail(key, f"{name!r}: no such metric or run-file quantity ({known})")
    return name


def _column(value, key, columns, fail) -> str:
    if value not in columns:
        fail(key, f"{value!r}: not an axis or recorded quantity ({', '.join(columns)})")
    return value


def _pareto(table, columns, fail) -> dict:
    if not isinstance(table, dict):
        fail("pareto", "must be a table")
    _known(table, ("cost", "goal", "target", "sense"), "pareto.", fail)
    out = {k: _column(table.get(k), f"pareto.{k}", columns, fail) for k in ("cost", "goal")}
    if ("target" in table) == ("sense" in table):
        fail("pareto", "give either target (goal brought to it) or sense ('min' or 'max')")
    if "target" in table:
        out["target"] = float(_number(table["target"], "pareto.target", fail))
    elif table["sense"] not in ("min", "max"):
        fail("pareto.sense", f"{table['sense']!r}: 'min' or 'max'")
    else:
        out["sense"] = table["sense"]
    return out


def targets(data, dotted: str) -> list:
    """The (container, key) pairs that ``dotted`` names in the scene data.

    A part is a table key, a list index, ``*`` (every element of a list) or the ``name`` of an
    element of a list of tables (``strings.s13.rest_length``).

    Raises
    ------
    KeyError
        A part that names nothing; the message says which and where.
    """
    found = [(None, data)]
    where = ""
    parts = dotted.split(".")
    for depth, part in enumerate(parts):
        step = []
        for _, node in found:
            step += [(node, k) for k in _children(node, part, where or "the scene")]
        found = [(parent, parent[k]) for parent, k in step]
        where = f"{where}.{part}" if where else part
        if depth == len(parts) - 1:
            return step
    return []


def _children(node, part, where) -> list:
    if isinstance(node, dict):
        if part not in node:
            raise KeyError(f"no key {part!r} in {where}")
        return [part]
    if isinstance(node, list):
        if part == "*":
            return list(range(len(node)))
        if part.lstrip("-").isdigit() and -len(node) <= int(part) < len(node):
            return [int(part)]
        named = [i for i, e in enumerate(node) if isinstance(e, dict) and e.get("name") == part]
        if named:
            return named
        raise KeyError(f"{part!r} is no index (0..{len(node) - 1}), '*' or name in {where}")
    raise KeyError(f"{where} is a value, not a table or list")


def apply(data: dict, axes, values) -> dict:
    """A deep copy of the scene ``data`` with each axis value written at its key."""
    out = copy.deepcopy(data)
    for axis, value in zip(axes, values, strict=True):
        for parent, k in targets(out, axis.key):
            parent[k] = _changed(parent[k], axis.op, value)
    return out


def _changed(old, op, v):
    if isinstance(old, list):
        if op == "stretch":
            return [x * v / old[-1] for x in old]
        return [_changed(x, op, v) for x in old]
    if op == "scale":
        return old * v
    if op == "magnitude":
        return math.copysign(v, old)
    return v  # set; stretch of a single number sets it


def case_count(spec: Spec) -> int:
    """How many cases ``spec`` has, without making them."""
    if spec.sampling == "grid":
        return math.prod(len(a.values) for a in spec.axes)
    return spec.n_cases


def cases(spec: Spec) -> Iterator[tuple]:
    """The cases' axis values, one tuple in axis order at a time (grid product, the last axis
    fastest, or Latin hypercube); check :func:`case_count` first."""
    if spec.sampling == "grid":
        sizes = [len(a.values) for a in spec.axes]
        for k in range(math.prod(sizes)):
            digits = []
            for n in reversed(sizes):
                k, i = divmod(k, n)
                digits.append(i)
            yield tuple(a.values[i] for a, i in zip(spec.axes, reversed(digits), strict=True))
        return
    from scipy.stats import qmc

    unit = qmc.LatinHypercube(d=len(spec.axes), rng=np.random.default_rng(spec.seed))
    points = unit.random(spec.n_cases)
    lo = np.array([a.values[0] for a in spec.axes])
    hi = np.array([a.values[1] for a in spec.axes])
    yield from (tuple(float(v) for v in lo + p * (hi - lo)) for p in points)
