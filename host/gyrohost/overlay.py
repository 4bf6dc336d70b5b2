"""Configuration overlays: a file of the keys to change merged into a rig configuration's TOML
data (``gyrotens run --overlay``, what ``gyrotens identify`` writes)."""

from gyrohost.errors import ConfigError


def merge_overlay(base: dict, overlay: dict, source: str, where: str = "") -> dict:
    """``base`` (a configuration's TOML data) with ``overlay``'s keys set in it.

    Tables merge key by key; an array of tables (``[[servos.servo]]``) merges entry by entry,
    each overlay entry into the base's entry of the same ``name``; any other value replaces the
    base's. ``source`` (the overlay file) is named in errors.

    Raises
    ------
    ConfigError
        An overlay table where the base has a value (or the reverse), or an array-of-tables
        entry without a ``name`` or with a name the base does not have.
    """
    out = dict(base)
    for key, value in overlay.items():
        here = f"{where}{key}"
        old = base.get(key)
        if isinstance(value, dict) or isinstance(old, dict):
            if old is not None and not (isinstance(value, dict) and isinstance(old, dict)):
                raise ConfigError(f"{source}: key '{here}': a table against a value or the reverse")
            out[key] = merge_overlay(old or {}, value, source, here + ".")
        elif _tables(value) and old is not None:
            out[key] = _merge_entries(old, value, source, here)
        else:
            out[key] = value
    return out


def _tables(value) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _merge_entries(base: list, overlay: list, source: str, where: str) -> list:
    if not _tables(base):
        raise ConfigError(f"{source}: key '{where}': an array of tables against a value")
    names = [entry.get("name") for entry in base]
    out = list(base)
    for i, entry in enumerate(overlay):
        name = entry.get("name")
        if name not in names:
            raise ConfigError(
                f"{source}: key '{where}[{i}].name': {name!r} names no entry of the "
                f"configuration (it has {', '.join(map(repr, names))})"
            )
        k = names.index(name)
        out[k] = merge_overlay(out[k], entry, source, f"{where}[{k}].")
    return out
