"""TOML tables into frozen dataclasses, checked key by key.

Every table maps onto one dataclass; a key the dataclass does not have, a value of the wrong
type or outside its range raises :class:`~gyrohost.errors.ConfigError` naming the file and the
dotted key (``servos.servo[1].pulley_radius_m``). Range and choice constraints live in each
field's metadata (:func:`spec`) so that every table is checked the same way; cross-field rules
live in each class's ``problems`` method. The rig's configuration (:mod:`gyrohost.config`) and
the simulated rig's (:mod:`gyrohost.simrig.config`) are both read this way.
"""

import math
import typing
from dataclasses import MISSING, fields, is_dataclass

from gyrohost.errors import ConfigError


def spec(*, lo=None, hi=None, choices=None, doc: str = "") -> dict:
    """A field's metadata: its range (``lo``, ``hi``), its allowed values, its unit or meaning."""
    return {"min": lo, "max": hi, "choices": choices, "doc": doc}


def build(cls: type, table: object, where: str, source: str):
    """An instance of the dataclass ``cls`` from the parsed TOML ``table`` at the dotted key
    ``where`` of the file ``source``; a field of type ``dict`` keeps its table as parsed (the
    module that knows its keys checks it)."""
    if not isinstance(table, dict):
        raise ConfigError(f"{source}: key '{where.rstrip('.') or '<root>'}' must be a table")
    hints = typing.get_type_hints(cls)
    known = {f.name: f for f in fields(cls) if not f.metadata.get("internal")}
    for key in table:
        if key not in known:
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
    obj = cls(**values)
    for sub, message in getattr(obj, "problems", lambda: [])():
        raise ConfigError(f"{source}: key '{where}{sub}': {message}")
    return obj


def _convert(hint, value, key: str, source: str):
    origin = typing.get_origin(hint)
    if is_dataclass(hint):
        return build(hint, value, key + ".", source)
    if hint is dict:
        if isinstance(value, dict):
            return value
        raise ConfigError(f"{source}: key '{key}' must be a table, got {type(value).__name__}")
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
    if not isinstance(value, list | tuple):  # a programme's edit may give a tuple
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
