"""Keys of a rig configuration still at the value the shipped lab-rig template gives them.

The template (``gyrohost/configs/lab-rig.toml``, package data) marks the keys a lab must fill in
with a comment on their line: ``# MEASURE`` (a dimension of the rig) or ``# CALIBRATE`` (a figure
found with the devices). A copy's key is a placeholder while its value equals the template's and
its line still carries the marker; deleting the marker says "measured, and it is this value".
A ``CALIBRATE`` key whose comment starts with neither ``datasheet value`` nor ``emulator value``
(the simulated rig's figure: the estimator's lags) is required, as the servos' zeros are:
``gyrotens run`` on real ports refuses a configuration that still has one.
"""

import re
from dataclasses import dataclass
from pathlib import Path

from gyrohost.config import ConfigError
from gyrohost.resources import shipped
from gyrotensegrity.textfile import read_text, read_toml

TEMPLATE = "lab-rig"
"""The shipped configuration whose marked keys are the placeholders."""

_TABLE = re.compile(r"^\s*(\[\[?)\s*([A-Za-z0-9_.]+)\s*\]\]?")
_KEY = re.compile(r"^\s*([A-Za-z0-9_]+)\s*=")
_MARKER = re.compile(r"#\s*(MEASURE|CALIBRATE)\b:?\s*(.*)$")
_STAND_IN = ("datasheet value", "emulator value")
"""How a ``CALIBRATE`` note starts when the figure can stand in until measured."""


@dataclass(frozen=True)
class Placeholder:
    """One key still at its template value.

    Attributes
    ----------
    key : str
        Dotted key, ``servos.servo[0].zero_position``.
    marker : str
        ``MEASURE`` or ``CALIBRATE``.
    note : str
        The rest of the template's comment (what to fill in).
    value : object
        The value (the template's).
    """

    key: str
    marker: str
    note: str
    value: object

    @property
    def required(self) -> bool:
        """A run on real ports needs it filled in (a calibration, not a datasheet's or the
        emulator's figure)."""
        return self.marker == "CALIBRATE" and not self.note.startswith(_STAND_IN)

    def describe(self) -> str:
        """``key = value (MARKER: note)``."""
        note = f": {self.note}" if self.note else ""
        return f"{self.key} = {self.value!r} ({self.marker}{note})"


def marked_keys(text: str) -> dict[str, tuple[str, str]]:
    """Dotted key -> (marker, note) of every line carrying a MEASURE or CALIBRATE comment."""
    out, prefix, counts = {}, "", {}
    for line in text.splitlines():
        table = _TABLE.match(line)
        if table:
            name = table.group(2)
            if table.group(1) == "[[":
                counts[name] = counts.get(name, -1) + 1
                prefix = f"{name}[{counts[name]}]."
            else:
                prefix = f"{name}."
            continue
        key, marker = _KEY.match(line), _MARKER.search(line)
        if key and marker:
            out[prefix + key.group(1)] = (marker.group(1), marker.group(2).strip())
    return out


def value_at(data: dict, key: str):
    """The value of a dotted key (``servos.servo[1].id``) in parsed TOML; KeyError if absent."""
    node = data
    for part in key.split("."):
        name, _, index = part.partition("[")
        node = node[name]
        if index:
            i = int(index.rstrip("]"))
            if i >= len(node):
                raise KeyError(key)
            node = node[i]
    return node


def find_placeholders(path: str | Path) -> list[Placeholder]:
    """The placeholders left in the configuration file ``path`` (module docstring).

    A required key the file leaves out (so at the default, the template's value) counts too.

    Raises
    ------
    ConfigError
        The file cannot be read or is not TOML.
    """
    template_path = shipped("config", TEMPLATE)
    template = read_toml(template_path, ConfigError)
    data = read_toml(path, ConfigError)
    try:
        still_marked = marked_keys(read_text(path))
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    found = []
    for key, (marker, note) in marked_keys(read_text(template_path)).items():
        placeholder = Placeholder(key, marker, note, value_at(template, key))
        try:
            same = value_at(data, key) == placeholder.value and key in still_marked
        except KeyError:
            same = placeholder.required and _servo_exists(data, key)
        if same:
            found.append(placeholder)
    return found


def _servo_exists(data: dict, key: str) -> bool:
    """A key of ``servos.servo[i]`` whose servo the file has (any other key: True)."""
    if not key.startswith("servos.servo["):
        return True
    try:
        value_at(data, key.rsplit(".", 1)[0])
    except KeyError:
        return False
    return True
