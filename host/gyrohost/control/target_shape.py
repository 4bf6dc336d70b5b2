"""A target shape: the rest lengths a plan must end at (``gyrotens plan --target-shape FILE``).

The file (TOML) holds one table of actuated strings' rest lengths, metres::

    [rest_length]
    s7 = 0.31
    s8 = 0.35

Strings not named end where they started (the scene's rest lengths). A landing at another
shape leaves the wheels' momentum on other axes of the body (``R^T H = h_b(r) omega_w`` at the
end), so a target shape widens what a structure can land at.
"""

import math
from pathlib import Path

import numpy as np

from gyrotensegrity.compat import tomllib
from gyrotensegrity.textfile import TextFileError, read_text

from .errors import PlanError

MATCH_M = 1e-4
"""How far (m) a given rest length of a string that follows another (the D-bar's n2-n4, whose
rest length the rhombus fixes) may lie from the one its leader's gives: a tenth of a
millimetre, below a servo's resolution."""


def load_target_shape(path) -> dict:
    """``{string name: rest length (m)}`` of a target-shape file.

    Raises
    ------
    PlanError
        The file cannot be read or parsed, or its ``rest_length`` table is missing, empty or
        holds a value that is not a positive finite number (the message names file and key).
    """
    path = Path(path)
    try:
        data = tomllib.loads(read_text(path))
    except TextFileError as exc:
        raise PlanError(str(exc)) from None
    except tomllib.TOMLDecodeError as exc:
        raise PlanError(f"{path}: cannot parse: {exc}") from None
    table = data.get("rest_length")
    if not isinstance(table, dict) or not table:
        raise PlanError(f"{path}: needs a [rest_length] table of string = metres")
    extra = sorted(set(data) - {"rest_length"})
    if extra:
        raise PlanError(f"{path}: unknown key(s) {', '.join(extra)} (only [rest_length])")
    out = {}
    for name, value in table.items():
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        if not (ok and math.isfinite(value) and value > 0.0):
            raise PlanError(
                f"{path}: rest_length.{name} = {value!r}: must be a positive number (m)"
            )
        out[name] = float(value)
    return out


def landing_coordinates(planner, rest: dict | None):
    """The coordinates (a,) m an :class:`.attitude_planner.AttitudePlanner` lands at for target
    rest lengths ``rest`` (:func:`target_coordinates` of its model), or None without them.

    Raises
    ------
    PlanError
        A planner that holds the rest lengths (mode ``wheels``) cannot land them elsewhere, or
        :func:`target_coordinates` refuses them.
    """
    if not rest:
        return None
    if planner.mode == "wheels":
        raise PlanError("a target shape needs the strings to move (not --wheels-only)")
    return target_coordinates(planner.model, rest)


def target_coordinates(model, rest: dict):
    """The reduced model's coordinates (a,) m at the landing for target rest lengths ``rest``
    of an :class:`.shape_attitude.AttitudeModel` ``model``: its start's where not given.

    Raises
    ------
    PlanError
        A named string is not actuated, the lengths leave the shape table's box, or a follower's
        length does not match its leader's.
    """
    names, shape = model.names, model.shape
    unknown = [n for n in rest if n not in names]
    if unknown:
        raise PlanError(
            f"target shape: string(s) {', '.join(unknown)} not actuated (the plan moves "
            f"{', '.join(names) or 'none'})"
        )
    lengths = shape.rest_lengths(shape.rest[None])[0]
    r = np.array([rest.get(n, v) for n, v in zip(names[: model.a], lengths, strict=False)])
    table = model.table
    for n, v, lo, hi in zip(names, r, table.lo, table.hi, strict=False):
        if not lo <= v <= hi:
            raise PlanError(
                f"target shape: {n} = {v:.4f} m is outside {lo:.4f} .. {hi:.4f} m, the rest "
                "lengths the planner's shape table holds (servo range, travel, taut strings)"
            )
    follows = shape.rest_lengths(r[None])[0]
    for n, v in zip(names, follows, strict=True):
        if n in rest and abs(rest[n] - v) > MATCH_M:
            raise PlanError(
                f"target shape: {n} = {rest[n]:.4f} m, but the shape its leader gives holds it at "
                f"{v:.4f} m; leave it out or give that"
            )
    return r
