"""The rig configuration a run log was recorded with: ``rig_config`` of its ``meta.json`` (the
configuration as the run loaded it, its file's path as ``source``).

``gyrotens identify`` and ``gyrotens noise`` take it from the logs, so a log of the real rig is
read with the real rig's configuration without being told; a ``--config`` given that differs
from what a log ran with is used, with a warning naming both.
"""

import json
import math
from dataclasses import asdict
from pathlib import Path

from gyrohost.config import RigConfig, load_rig_config, rig_config_from_dict
from gyrohost.errors import ConfigError
from gyrohost.resources import resolve
from gyrohost.run.errors import LogError
from gyrohost.run.log import read_meta


def recorded_config(folder: Path) -> RigConfig:
    """The configuration the log ``folder`` ran with.

    Raises
    ------
    ConfigError
        ``meta.json`` is missing, unreadable or holds no ``rig_config`` (the message says to
        give ``--config``), or its ``rig_config`` does not load.
    """
    try:
        data = dict(read_meta(folder).get("rig_config") or {})
    except LogError as exc:
        raise ConfigError(f"{exc}: give the configuration with --config") from None
    if not data:
        raise ConfigError(f"{folder}/meta.json names no rig_config: give it with --config")
    source = str(data.pop("source", f"{folder}/meta.json"))
    return rig_config_from_dict(_without_infinities(data), source)


def _without_infinities(table: dict) -> dict:
    """``table`` without its infinite values: a key a file leaves out to say "unchecked"
    (``run.max_tilt_rad``) is infinite once loaded, and a file may not write it so."""
    out = {}
    for key, value in table.items():
        if isinstance(value, dict):
            out[key] = _without_infinities(value)
        elif not (isinstance(value, float) and math.isinf(value)):
            out[key] = value
    return out


def config_for_logs(logs: list[Path], given: str | None) -> tuple[RigConfig, list[str]]:
    """The configuration to read ``logs`` with, and warnings: ``given`` (a file or shipped name)
    when given, else the first log's; a warning for each log that ran with another.

    Raises
    ------
    ConfigError
        As :func:`recorded_config` (only when nothing is given), or ``given`` does not load.
    """
    if given is not None:
        config = load_rig_config(resolve("config", given))
    else:
        config = recorded_config(logs[0])
    warnings = []
    for log in logs:
        try:
            recorded = recorded_config(log)
        except ConfigError:
            continue  # the log's own loading names what is missing
        if _content(recorded) != _content(config):
            warnings.append(
                f"{log} ran with the configuration {recorded.source}, read here with "
                f"{config.source}"
            )
    return config, warnings


def _content(config: RigConfig) -> str:
    """The configuration's keys and values as JSON (tuples as lists, the source left out)."""
    data = asdict(config)
    data.pop("source")
    return json.dumps(data, sort_keys=True)
