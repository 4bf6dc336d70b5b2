"""Files shipped with the package: scenes, rig configurations and schedules; safe file names.

Scenes ship with the model library (``gyrotensegrity/scenes/*.toml``), rig configurations and
schedules with the host (``gyrohost/configs/*.toml``, ``gyrohost/schedules/*.toml``); they are
found with :mod:`importlib.resources`, so they work from a source checkout, an editable install
and a wheel alike, whatever the current directory.

A user's argument is resolved by :func:`resolve`: an existing file (relative to ``base``, the
current directory by default) wins; otherwise a bare name such as ``dbar-gyro``, ``sim-rig`` or
``paper`` (``.toml`` optional) names a shipped file; otherwise :class:`ResourceError` lists the
shipped names.
"""

import re
from importlib import resources
from pathlib import Path

from gyrohost.errors import GyrohostError

KINDS = {
    "scene": ("gyrotensegrity", "scenes"),
    "config": ("gyrohost", "configs"),
    "schedule": ("gyrohost", "schedules"),
}
"""Kind of shipped file -> (package, folder inside it)."""


class ResourceError(GyrohostError, ValueError):
    """A file argument is neither an existing file nor the name of a shipped one."""


def shipped_dir(kind: str) -> Path:
    """The folder of the shipped files of ``kind`` (``"scene"``, ``"config"``, ``"schedule"``).

    Raises
    ------
    KeyError
        ``kind`` is not one of :data:`KINDS`.
    """
    package, folder = KINDS[kind]
    # Both packages are regular (not zipped) directories, so the traversable is a real path.
    return Path(str(resources.files(package).joinpath(folder)))


def shipped_names(kind: str) -> list[str]:
    """Names (file stems) of the shipped files of ``kind``, sorted."""
    return sorted(p.stem for p in shipped_dir(kind).glob("*.toml"))


def shipped(kind: str, name: str) -> Path:
    """The shipped file of ``kind`` called ``name`` (with or without ``.toml``).

    Raises
    ------
    ResourceError
        No shipped file of that name; the message lists the shipped names.
    """
    stem = name.removesuffix(".toml")
    path = shipped_dir(kind) / f"{stem}.toml"
    if "/" in name or not stem or not path.is_file():
        raise ResourceError(
            f"{name}: not a shipped {kind} (shipped: {', '.join(shipped_names(kind))})"
        )
    return path


def resolve(kind: str, arg: str | Path, base: str | Path | None = None) -> Path:
    """The file ``arg`` names: an existing file, else a shipped file of ``kind``.

    Parameters
    ----------
    kind : {"scene", "config", "schedule"}
        Which shipped files a bare name is looked up among.
    arg : str or Path
        A path (relative paths start from ``base``) or a bare shipped name.
    base : str or Path, optional
        Folder that a relative ``arg`` starts from; the current directory by default.

    Returns
    -------
    Path
        The file, absolute.

    Raises
    ------
    ResourceError
        ``arg`` is no file and no shipped name; the message names where it looked and lists
        the shipped names.
    """
    path = Path(base or ".") / Path(arg).expanduser()
    if path.is_file():
        return path.resolve()
    text = str(arg)
    if "/" not in text:
        try:
            return shipped(kind, text)
        except ResourceError:
            pass
    raise ResourceError(
        f"{arg}: no such file{f' in {base}' if base else ''} and no shipped {kind} of that name "
        f"(shipped: {', '.join(shipped_names(kind))})"
    )


def safe_name(text: str, fallback: str = "run") -> str:
    """``text`` (a name read from a file: a schedule's, a scene's) made one safe path component.

    Characters other than ASCII letters, digits, ``.``, ``_``, ``+`` and ``-`` become ``_`` (a
    ``/`` can no longer leave the chosen folder), leading dots are dropped (no ``..``, no hidden
    file) and the name is cut to 64 characters; ``fallback`` if nothing is left.

    Examples
    --------
    >>> safe_name("../../x"), safe_name("tilt 0.3 rad"), safe_name("..")
    ('_.._x', 'tilt_0.3_rad', 'run')
    """
    name = re.sub(r"[^A-Za-z0-9._+-]", "_", str(text)).lstrip(".")[:64]
    return name or fallback


__all__ = [
    "KINDS",
    "ResourceError",
    "resolve",
    "safe_name",
    "shipped",
    "shipped_dir",
    "shipped_names",
]
