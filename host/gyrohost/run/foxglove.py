"""A run log's rows as JSON messages that Foxglove (and any MCAP reader) opens.

Every log stream is one channel, topic ``/<stream>``, with a JSON schema of its columns
(schema encoding ``jsonschema``, message encoding ``json``): one message per row, an object of
column -> value (NaN as ``null``; JSON has no NaN). Rows of node positions (``nodes``: the
estimate; ``truth``: the simulated rig's truth) also give a 3D scene of the structure on
``/scene/estimate`` and ``/scene/truth`` (schema ``foxglove.SceneUpdate``, JSON): bars as thick
lines, strings as thin lines, wheels as cylinders about their bars, all in the frame ``world`` of
the scene (z up), so Foxglove's 3D panel shows the D-bar moving. A scene is sent at most every
:data:`SCENE_PERIOD_S` of log time (the rows themselves all go out): the 3D view needs no more,
and each update costs the loop about 0.3 ms.

A message's log time is the log's creation (``meta.json`` ``created_unix_s``) plus the row's
``t_s``, ns since the Unix epoch (a row without a time, ``t_s`` NaN, at the creation).
"""

import json
import math
from dataclasses import dataclass

import numpy as np

from gyrohost.run.log import format_value

FRAME = "world"
SCENE_TOPICS = {"nodes": "/scene/estimate", "truth": "/scene/truth"}
"""Stream of node positions -> its 3D scene topic."""
SCENE_COLORS = {"nodes": (0.12, 0.47, 0.71), "truth": (0.3, 0.3, 0.3)}
"""RGB of each scene: the estimate blue, the truth grey."""
SCENE_PERIOD_S = 0.04
"""Shortest log time between two scene updates of one stream, s (25 Hz)."""
BAR_THICKNESS_M = 0.008
STRING_THICKNESS_M = 0.002


@dataclass(frozen=True)
class ChannelSpec:
    """One channel: topic, schema name and JSON schema (a dict)."""

    topic: str
    schema_name: str
    schema: dict

    def schema_bytes(self) -> bytes:
        return json.dumps(self.schema).encode()


def stream_schema(name: str, columns, text_columns=(), description: str = "") -> dict:
    """The JSON schema of one stream's rows: an object with one property per column (numbers,
    ``null`` for NaN; strings for ``text_columns``)."""
    text = set(text_columns)
    return {
        "title": f"gyrotens.{name}",
        "description": description,
        "type": "object",
        "properties": {
            c: {"type": "string"} if c in text else {"type": ["number", "null"]} for c in columns
        },
    }


class RowJson:
    """One stream's rows as JSON objects (numbers; ``null`` for NaN and infinities; strings in
    the text columns), made from the row's CSV texts: a finite number's shortest exact text
    is a JSON number already, so a row costs a join instead of a float conversion and an
    encoding per value (the run loop writes some 15 rows per 10 ms tick).

    Parameters
    ----------
    columns : sequence of str
    text_columns : sequence of str
        Columns whose values are strings.
    """

    def __init__(self, columns, text_columns=()):
        text = set(text_columns)
        self.keys = [json.dumps(c) + ":" for c in columns]
        self.text_index = [i for i, c in enumerate(columns) if c in text]

    def json(self, values, texts=None) -> bytes:
        """The JSON bytes of one row; ``texts`` its values as
        :func:`~gyrohost.run.log.format_value` writes them (made here when None)."""
        if texts is None:
            texts = [format_value(v) for v in values]
        items = ["null" if t in _NOT_FINITE else t for t in texts]
        for i in self.text_index:
            items[i] = json.dumps(str(values[i]))
        return ("{" + ",".join(map(str.__add__, self.keys, items)) + "}").encode()


_NOT_FINITE = frozenset(("nan", "inf", "-inf"))


def log_time_ns(t0_unix_s: float, t_s) -> int:
    """Log time of a row stamped ``t_s`` (s since the log's creation at ``t0_unix_s``), ns."""
    t = float(t_s)
    return int(round((t0_unix_s + (t if math.isfinite(t) else 0.0)) * 1e9))


def _vec(p) -> dict:
    return {"x": float(p[0]), "y": float(p[1]), "z": float(p[2])}


IDENTITY = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}


def _color(rgb, alpha: float = 1.0) -> dict:
    return {"r": rgb[0], "g": rgb[1], "b": rgb[2], "a": alpha}


def z_to(direction) -> dict:
    """The quaternion turning +z onto ``direction`` (3,) (a cylinder's axis)."""
    dx, dy, dz = (float(v) for v in direction)
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    w = 1.0 + dz / norm
    if w < 1e-9:  # direction is -z: half a turn about x
        return {"x": 1.0, "y": 0.0, "z": 0.0, "w": 0.0}
    # (z x d, 1 + z.d) with d the unit direction, normalised
    x, y = -dy / norm, dx / norm
    q = math.sqrt(x * x + y * y + w * w)
    return {"x": x / q, "y": y / q, "z": 0.0, "w": w / q}


def _line(points, thickness_m: float, rgb) -> dict:
    return {
        "type": 2,  # LINE_LIST: each pair of points one segment
        "pose": {"position": _vec((0, 0, 0)), "orientation": IDENTITY},
        "thickness": thickness_m,
        "scale_invariant": False,
        "points": [_vec(p) for p in points],
        "color": _color(rgb),
        "colors": [],
        "indices": [],
    }


class SceneShapes:
    """The structure of a scene as ``foxglove.SceneUpdate`` messages from node positions.

    Parameters
    ----------
    scene : gyrotensegrity.Scene
        Bars (with their wheels) and strings, by node name.
    """

    def __init__(self, scene):
        self.bars = [(b.start, b.end) for b in scene.bars]
        self.wheels = [(b.start, b.end, b.wheel) for b in scene.bars if b.wheel is not None]
        self.strings = [(s.start, s.end) for s in scene.strings]
        self.nodes = sorted({n for pair in self.bars + self.strings for n in pair})

    def node_columns(self, columns) -> dict | None:
        """Node name -> the indices of its ``<node>_{x,y,z}_m`` columns in ``columns``; None if
        a node of the structure has none."""
        index = {c: i for i, c in enumerate(columns)}
        cols = {n: [index.get(f"{n}_{a}_m") for a in "xyz"] for n in self.nodes}
        return None if any(None in c for c in cols.values()) else cols

    @staticmethod
    def positions(node_columns: dict, values) -> dict | None:
        """Node name -> position (3,), m, of one row (:meth:`node_columns`); None if one is not
        finite in this row."""
        out = {n: np.array([float(values[i]) for i in cols]) for n, cols in node_columns.items()}
        finite = all(math.isfinite(x) for p in out.values() for x in p)
        return out if finite else None

    def update(self, positions: dict, t_ns: int, entity: str, rgb) -> dict:
        """One SceneUpdate: entity ``entity`` (replacing its previous one) at time ``t_ns``."""
        bars = [positions[n] for pair in self.bars for n in pair]
        strings = [positions[n] for pair in self.strings for n in pair]
        cylinders = []
        for start, end, wheel in self.wheels:
            a, b = positions[start], positions[end]
            cylinders.append(
                {
                    "pose": {"position": _vec((a + b) / 2), "orientation": z_to(b - a)},
                    "size": _vec((2 * wheel.radius, 2 * wheel.radius, wheel.thickness)),
                    "bottom_scale": 1.0,
                    "top_scale": 1.0,
                    "color": _color(rgb, 0.6),
                }
            )
        stamp = {"sec": t_ns // 1_000_000_000, "nsec": t_ns % 1_000_000_000}
        lines = [_line(bars, BAR_THICKNESS_M, rgb), _line(strings, STRING_THICKNESS_M, rgb)]
        return {
            "deletions": [],
            "entities": [
                {
                    "timestamp": stamp,
                    "frame_id": FRAME,
                    "id": entity,
                    "lifetime": {"sec": 0, "nsec": 0},
                    "frame_locked": False,
                    "metadata": [],
                    "arrows": [],
                    "cubes": [],
                    "spheres": [],
                    "cylinders": cylinders,
                    "lines": lines if strings else lines[:1],
                    "triangles": [],
                    "texts": [],
                    "models": [],
                }
            ],
        }


class LogChannels:
    """The channels and messages of one log: a stream's rows and, for node positions, scenes.

    Parameters
    ----------
    t0_unix_s : float
        The log's creation, s since the Unix epoch (``meta.json`` ``created_unix_s``).
    scene : gyrotensegrity.Scene or None
        The run's scene; None: no scene channels.
    """

    def __init__(self, t0_unix_s: float, scene=None):
        self.t0_unix_s = t0_unix_s
        self.shapes = None if scene is None else SceneShapes(scene)
        self.columns: dict[str, tuple] = {}
        self.scene_columns: dict[str, dict] = {}
        self.last_scene_ns: dict[str, int] = {}
        self._rows: dict[str, RowJson] = {}

    def open(self, name: str, columns, text_columns=(), description: str = "") -> list:
        """The :class:`ChannelSpec` of stream ``name`` and, for node positions, of its scene."""
        self.columns[name] = tuple(columns)
        self._rows[name] = RowJson(columns, text_columns)
        specs = [
            ChannelSpec(f"/{name}", f"gyrotens.{name}",
                        stream_schema(name, columns, text_columns, description))
        ]  # fmt: skip
        if self.shapes is not None and name in SCENE_TOPICS:
            node_columns = self.shapes.node_columns(columns)
            if node_columns is not None:
                self.scene_columns[name] = node_columns
                specs.append(ChannelSpec(SCENE_TOPICS[name], "foxglove.SceneUpdate", SCENE_UPDATE))
        return specs

    def messages(self, name: str, values, texts=None) -> list[tuple[str, int, bytes]]:
        """(topic, log time ns, JSON bytes) of one row of stream ``name``: the row, then its
        scene update if the stream has one and the last is :data:`SCENE_PERIOD_S` old.
        ``texts``: the values as the CSV has them (``gyrohost.run.log.format_value``), if
        formatted already."""
        columns = self.columns[name]
        t_ns = log_time_ns(self.t0_unix_s, values[0] if columns[0] == "t_s" else math.nan)
        row = self._rows[name].json(values, texts)
        out = [(f"/{name}", t_ns, row)]
        node_columns = self.scene_columns.get(name)
        last = self.last_scene_ns.get(name)
        if node_columns is None or last is not None and t_ns - last < SCENE_PERIOD_S * 1e9:
            return out
        positions = self.shapes.positions(node_columns, values)
        if positions is not None:
            self.last_scene_ns[name] = t_ns
            scene = self.shapes.update(positions, t_ns, name, SCENE_COLORS[name])
            out.append((SCENE_TOPICS[name], t_ns, json.dumps(scene).encode()))
        return out


def _object(properties: dict, description: str = "") -> dict:
    return {"type": "object", "description": description, "properties": properties}


_NUMBER = {"type": "number"}
_VECTOR3 = _object({a: _NUMBER for a in "xyz"})
_QUATERNION = _object({a: _NUMBER for a in "xyzw"})
_POSE = _object({"position": _VECTOR3, "orientation": _QUATERNION})
_COLOR = _object({c: _NUMBER for c in "rgba"}, "RGBA, each in [0, 1]")
_TIME = _object({"sec": {"type": "integer"}, "nsec": {"type": "integer"}})
_ANY_LIST = {"type": "array", "items": {"type": "object"}}

SCENE_UPDATE = {
    "title": "foxglove.SceneUpdate",
    "description": "An update to the entities displayed in a 3D scene (the fields written here; "
    "Foxglove's schema of that name)",
    **_object(
        {
            "deletions": _ANY_LIST,
            "entities": {
                "type": "array",
                "items": _object(
                    {
                        "timestamp": _TIME,
                        "frame_id": {"type": "string"},
                        "id": {"type": "string"},
                        "lifetime": _TIME,
                        "frame_locked": {"type": "boolean"},
                        "metadata": _ANY_LIST,
                        "arrows": _ANY_LIST,
                        "cubes": _ANY_LIST,
                        "spheres": _ANY_LIST,
                        "cylinders": {
                            "type": "array",
                            "items": _object(
                                {
                                    "pose": _POSE,
                                    "size": _VECTOR3,
                                    "bottom_scale": _NUMBER,
                                    "top_scale": _NUMBER,
                                    "color": _COLOR,
                                }
                            ),
                        },
                        "lines": {
                            "type": "array",
                            "items": _object(
                                {
                                    "type": {"type": "integer", "enum": [0, 1, 2]},
                                    "pose": _POSE,
                                    "thickness": _NUMBER,
                                    "scale_invariant": {"type": "boolean"},
                                    "points": {"type": "array", "items": _VECTOR3},
                                    "color": _COLOR,
                                    "colors": {"type": "array", "items": _COLOR},
                                    "indices": {"type": "array", "items": {"type": "integer"}},
                                }
                            ),
                        },
                        "triangles": _ANY_LIST,
                        "texts": _ANY_LIST,
                        "models": _ANY_LIST,
                    }
                ),
            },
        }
    ),
}
"""JSON schema of the ``foxglove.SceneUpdate`` messages written here (bars, strings, wheels)."""
