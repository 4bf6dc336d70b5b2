"""Schedules: piecewise-linear rest lengths of the actuated strings and wheel speeds over time.

A :class:`Schedule` holds one time grid ``t`` (k,) s and, for each actuated string (by its
scene name), the rest lengths (k,) m at those times; optionally, for wheels (by the scene name
of their bar), the commanded spin (k,) rad/s. Between samples values are linear; before the
first and after the last sample they are held. Strings of the scene that a schedule does not
name keep the scene's own schedule; wheels it does not name keep the scene's spin.

File format (TOML, or the same keys in JSON; ``docs/schedule.md``)::

    [schedule]
    name = "paper"
    t_s = [0.0, 0.1, ...]            # strictly increasing, s
    purpose = "identification"       # optional: "run" (the default) or "identification"

    [rest_length_m]                  # one array per actuated string, same length as t_s, m
    s13 = [0.431, 0.421, ...]
    s24 = [0.431, 0.440, ...]

    [wheel_speed_rad_s]              # optional: the wheel on each named bar, rad/s about +b
    b12 = [74.9, 74.9, 86.1, ...]
"""

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gyrotensegrity.compat import tomllib
from gyrotensegrity.textfile import TextFileError, read_text

from .errors import ScheduleError

PURPOSES = ("run", "identification")
"""What a schedule is for. An ``identification`` schedule records the data ``gyrotens identify``
fits, on a rig whose parameters are not yet known: its run's estimate, on the scene still to be
identified, may diverge without failing the run (docs/schedule.md)."""

SPLICE_GAP_S = 1e-9
"""Samples nearer than this to a splice's time give way to the splice point, s."""


@dataclass(frozen=True)
class Limits:
    """What the servos and the geometry allow a schedule to command.

    Parameters
    ----------
    max_speed_m_s : float, m/s
        Largest rate of change of any rest length (servo speed times pulley radius).
    min_length_m, max_length_m : float, m
        Range of every commanded rest length.
    min_diagonal_m : float, m
        Smallest n1-n3 and n2-n4 distance the planner may command: below it the wheels of
        neighbouring bars touch (default 4 wheel radii of the D-bar, 0.124 m).
    string_ranges_m : tuple of (str, float, float)
        ``(string, min_length_m, max_length_m)`` of strings with a range of their own (each
        servo's); it replaces the common range for that string.
    max_wheel_speed_rad_s : float, rad/s
        Largest |spin| a schedule commands: the wheel board's default SPEED_MAX, 157.08 rad/s
        (docs/hardware.md); a run's ``max_wheel_speed_rad_s`` may set less.
    max_wheel_accel_rad_s2 : float, rad/s^2
        Largest rate of change of a commanded spin: the board's setpoint ramp ACCEL_RAD_S2,
        100 rad/s^2 by default (it brakes at DECEL 200; the motor manages 190 at full drive).
    """

    max_speed_m_s: float = 0.05
    min_length_m: float = 0.0
    max_length_m: float = 1.0
    min_diagonal_m: float = 0.124
    string_ranges_m: tuple = ()
    max_wheel_speed_rad_s: float = 157.08
    max_wheel_accel_rad_s2: float = 100.0

    def __post_init__(self):
        for key in (
            "max_speed_m_s",
            "max_length_m",
            "min_diagonal_m",
            "max_wheel_speed_rad_s",
            "max_wheel_accel_rad_s2",
        ):
            value = getattr(self, key)
            if not (math.isfinite(value) and value > 0.0):
                raise ScheduleError(f"limits: {key} must be a positive number, got {value}")
        if not 0.0 <= self.min_length_m < self.max_length_m:
            raise ScheduleError(
                f"limits: need 0 <= min_length_m < max_length_m, got "
                f"{self.min_length_m} and {self.max_length_m}"
            )

    @classmethod
    def from_servos(cls, servos, min_diagonal_m=0.124):
        """The tightest limits of a set of :class:`gyrohost.config.ServoConfig`."""
        if not servos:
            raise ScheduleError("limits: no servos configured")
        return cls(
            max_speed_m_s=min(s.max_speed_m_s for s in servos),
            min_length_m=max(s.min_length_m for s in servos),
            max_length_m=min(s.max_length_m for s in servos),
            min_diagonal_m=min_diagonal_m,
        )

    @classmethod
    def per_string(cls, servos, min_diagonal_m=0.124):
        """Each servo's length range for the string it winds; the slowest servo's speed."""
        if not servos:
            raise ScheduleError("limits: no servos configured")
        return cls(
            max_speed_m_s=min(s.max_speed_m_s for s in servos),
            min_length_m=min(s.min_length_m for s in servos),
            max_length_m=max(s.max_length_m for s in servos),
            min_diagonal_m=min_diagonal_m,
            string_ranges_m=tuple(
                (s.string or s.name, s.min_length_m, s.max_length_m) for s in servos
            ),
        )

    def range_of(self, name: str) -> tuple[float, float]:
        """``(min_length_m, max_length_m)`` of string ``name``, m."""
        for string, lo, hi in self.string_ranges_m:
            if string == name:
                return lo, hi
        return self.min_length_m, self.max_length_m


@dataclass(frozen=True)
class Schedule:
    """Piecewise-linear rest lengths of named strings.

    Parameters
    ----------
    names : tuple of str, (s,)
        Scene names of the scheduled strings.
    t : ndarray, shape (k,), s
        Strictly increasing times.
    rest_length : ndarray, shape (k, s), m
        Rest length of each string (column) at each time (row).
    name : str
    wheels : tuple of str, (w,)
        Scene names of the bars whose wheels the schedule spins (none: the scene's spins).
    wheel_speed : ndarray, shape (k, w), rad/s
        Commanded spin of each of those wheels, about +b of its bar.
    purpose : str
        One of :data:`PURPOSES`.
    """

    names: tuple
    t: np.ndarray
    rest_length: np.ndarray
    name: str = "schedule"
    wheels: tuple = ()
    wheel_speed: np.ndarray | None = None
    purpose: str = "run"

    def __post_init__(self):
        t = np.asarray(self.t, float)
        v = np.asarray(self.rest_length, float)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "rest_length", v)
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "wheels", tuple(self.wheels))
        w = np.zeros((t.size, 0)) if self.wheel_speed is None else self.wheel_speed
        object.__setattr__(self, "wheel_speed", np.asarray(w, float))
        where = f"schedule {self.name}"
        if self.purpose not in PURPOSES:
            raise ScheduleError(
                f"{where}: purpose {self.purpose!r} is none of {', '.join(PURPOSES)}"
            )
        if t.ndim != 1 or t.size == 0:
            raise ScheduleError(f"{where}: t must be a non-empty 1-D array")
        if v.shape != (t.size, len(self.names)):
            raise ScheduleError(
                f"{where}: rest_length has shape {v.shape}, expected {(t.size, len(self.names))}"
            )
        if self.wheel_speed.shape != (t.size, len(self.wheels)):
            raise ScheduleError(
                f"{where}: wheel_speed has shape {self.wheel_speed.shape}, expected "
                f"{(t.size, len(self.wheels))}"
            )
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
            raise ScheduleError(f"{where}: times and rest lengths must be finite")
        if not np.all(np.isfinite(self.wheel_speed)):
            raise ScheduleError(f"{where}: wheel speeds must be finite")
        bad = np.flatnonzero(np.diff(t) <= 0.0)
        if bad.size:
            raise ScheduleError(f"{where}: t[{bad[0] + 1}] does not increase")
        if np.any(v < 0.0):
            k, s = np.argwhere(v < 0.0)[0]
            raise ScheduleError(f"{where}: {self.names[s]} is negative at t = {t[k]:g} s")

    @property
    def t_end(self) -> float:
        """Time of the last sample, s."""
        return float(self.t[-1])

    def __call__(self, t: float) -> np.ndarray:
        """Rest lengths (s,) m at time ``t`` (s)."""
        return np.array([np.interp(t, self.t, col) for col in self.rest_length.T])

    def wheel_speeds(self, t: float) -> np.ndarray:
        """Commanded spins (w,) rad/s of the scheduled wheels at time ``t`` (s)."""
        return np.array([np.interp(t, self.t, col) for col in self.wheel_speed.T])

    def max_speeds(self) -> np.ndarray:
        """Largest |d rest_length / dt| of each string, shape (s,), m/s."""
        if self.t.size < 2:
            return np.zeros(len(self.names))
        rates = np.diff(self.rest_length, axis=0) / np.diff(self.t)[:, None]
        return np.max(np.abs(rates), axis=0)

    def problems(self, limits: Limits) -> list[str]:
        """Violations of the servo limits (speed and length range) and of the wheels' (speed
        and acceleration), as messages."""
        out = self._wheel_problems(limits)
        for name, speed in zip(self.names, self.max_speeds(), strict=True):
            if speed > limits.max_speed_m_s * (1.0 + 1e-9):
                out.append(f"{name}: speed {speed:.4g} m/s exceeds {limits.max_speed_m_s:g} m/s")
        lo, hi = self.rest_length.min(axis=0), self.rest_length.max(axis=0)
        for name, a, b in zip(self.names, lo, hi, strict=True):
            low, high = limits.range_of(name)
            if a < low - 1e-12 or b > high + 1e-12:  # a plan clipped to a bound ends on it
                out.append(f"{name}: rest length {a:.4g}..{b:.4g} m outside [{low:g}, {high:g}] m")
        return out

    def _wheel_problems(self, limits: Limits) -> list[str]:
        out = []
        if not self.wheels:
            return out
        fastest = np.max(np.abs(self.wheel_speed), axis=0)
        accel = np.zeros(len(self.wheels))
        if self.t.size > 1:
            rates = np.diff(self.wheel_speed, axis=0) / np.diff(self.t)[:, None]
            accel = np.max(np.abs(rates), axis=0)
        for name, w, a in zip(self.wheels, fastest, accel, strict=True):
            if w > limits.max_wheel_speed_rad_s * (1.0 + 1e-9):
                out.append(f"wheel {name}: {w:.4g} rad/s exceeds {limits.max_wheel_speed_rad_s:g}")
            if a > limits.max_wheel_accel_rad_s2 * (1.0 + 1e-9):
                out.append(
                    f"wheel {name}: {a:.4g} rad/s^2 exceeds {limits.max_wheel_accel_rad_s2:g}"
                )
        return out

    def bind(self, model):
        """Column of each scheduled string in the model's input, list of int.

        Raises
        ------
        ScheduleError
            A scheduled string is not in the model's scene.
        """
        strings = [s.name for s in model.scene.strings]
        return self._positions(self.names, strings, "string(s)", "", model)

    def bind_wheels(self, model):
        """Index of each scheduled wheel in the model's wheel order (scene bar order), list of
        int.

        Raises
        ------
        ScheduleError
            A scheduled wheel's bar is not a bar with a wheel in the model's scene.
        """
        bars = [model.scene.bars[b].name for b in model.wheel_bars]
        return self._positions(self.wheels, bars, "wheel(s) on", "wheels on ", model)

    def _positions(self, wanted, available, what, has, model) -> list[int]:
        missing = [n for n in wanted if n not in available]
        if missing:
            raise ScheduleError(
                f"schedule {self.name}: {what} {', '.join(missing)} not in scene "
                f"{model.scene.name} (it has {has}{', '.join(available) or 'none'})"
            )
        return [available.index(n) for n in wanted]

    def input_at(self, model, t: float) -> np.ndarray:
        """The model's input ``u`` at ``t`` (s): the scene's input with the scheduled rest
        lengths and wheel speeds replaced; shape (alpha + n_w,).

        Raises
        ------
        ScheduleError
            A scheduled wheel is torque-driven in the model (its spin is a state, not an input).
        """
        u = model.input_at(t)
        u[self.bind(model)] = self(t)
        wheels = self.bind_wheels(model)
        bars = model.scene.bars
        torque = [n for n, i in zip(self.wheels, wheels, strict=True)
                  if bars[model.wheel_bars[i]].wheel.mode != "speed"]  # fmt: skip
        if torque:
            raise ScheduleError(
                f"schedule {self.name}: the wheel(s) on {', '.join(torque)} are torque-driven in "
                f"scene {model.scene.name}: their spin is no input of the model"
            )
        u[[model.alpha + i for i in wheels]] = self.wheel_speeds(t)
        return u

    def splice(self, other: "Schedule", t_s: float) -> "Schedule":
        """This schedule up to ``t_s`` (s), then ``other`` (same strings) from ``t_s`` on.

        Raises
        ------
        ScheduleError
            The strings differ, or the rest lengths would jump at ``t_s`` by more than
            0.1 mm (a re-planned follower string starts on the exact rhombus geometry, the running
            schedule between its samples on a chord of it: tens of micrometres apart).
        """
        if other.names != self.names or other.wheels != self.wheels:
            raise ScheduleError(
                f"splice: strings {other.names} and wheels {other.wheels} differ from "
                f"{self.names} and {self.wheels}"
            )
        here = self(t_s)
        jump = np.max(np.abs(other(t_s) - here), initial=0.0)  # none: wheels only
        if jump > 1e-4:
            raise ScheduleError(f"splice at {t_s:g} s: rest lengths jump by {jump:.3g} m")
        # samples within SPLICE_GAP_S of t_s are dropped: a float sum of ticks lands 1e-16 s
        # off a knot, and a rate over that gap is round-off over round-off
        head = self.t < t_s - SPLICE_GAP_S
        tail = other.t > t_s + SPLICE_GAP_S
        t = np.concatenate([self.t[head], [t_s], other.t[tail]])
        v = np.vstack([self.rest_length[head], here, other.rest_length[tail]])
        w = np.vstack([self.wheel_speed[head], self.wheel_speeds(t_s), other.wheel_speed[tail]])
        return Schedule(self.names, t, v, self.name, self.wheels, w, self.purpose)

    def join(self, other: "Schedule", t_s: float, limits: Limits) -> "Schedule":
        """This schedule up to ``t_s`` (s), then a straight line to ``other`` (same strings and
        wheels) at the first of its samples that a move at ``limits``' rates reaches (rest
        lengths at ``max_speed_m_s``, spins at ``max_wheel_accel_rad_s2``), then ``other``.

        A re-plan made from the estimate at ``t`` but taken at ``t_s > t`` (it ran in a
        thread) departs from the schedule played since ``t``; :meth:`splice` at ``t_s`` would
        make the servos jump by that difference. The line is the fastest move the limits allow
        onto the new plan; where ``other`` ends first, its last values are reached as fast.
        """
        if other.names != self.names or other.wheels != self.wheels:
            return self.splice(other, t_s)  # raises, naming both
        here, spins = self(t_s), self.wheel_speeds(t_s)

        def move_s(k):  # the time a move from here to other's sample k takes at the limits
            rest = np.max(np.abs(other.rest_length[k] - here), initial=0.0)
            spin = np.max(np.abs(other.wheel_speed[k] - spins), initial=0.0)
            return max(rest / limits.max_speed_m_s, spin / limits.max_wheel_accel_rad_s2)

        later = np.flatnonzero(other.t > t_s + SPLICE_GAP_S)
        # a round-off short of the limit still reaches (Schedule.problems allows as much)
        reached = [k for k in later if other.t[k] - t_s >= move_s(k) * (1.0 - 1e-9)]
        head = self.t < t_s - SPLICE_GAP_S
        if reached:
            k = reached[0]
            t = np.concatenate([self.t[head], [t_s], other.t[k:]])
            rest, wheels = other.rest_length[k:], other.wheel_speed[k:]
        else:
            last = len(other.t) - 1
            t = np.concatenate([self.t[head], [t_s, t_s + move_s(last)]])
            rest, wheels = other.rest_length[last:], other.wheel_speed[last:]
        v = np.vstack([self.rest_length[head], here, rest])
        w = np.vstack([self.wheel_speed[head], spins, wheels])
        return Schedule(self.names, t, v, self.name, self.wheels, w, self.purpose)

    def to_dict(self) -> dict:
        """Plain data in the file layout (see the module docstring)."""
        out = {
            "schedule": {"name": self.name, "t_s": self.t.tolist(), **self._purpose_key()},
            "rest_length_m": {n: self.rest_length[:, i].tolist() for i, n in enumerate(self.names)},
        }
        if self.wheels:
            out["wheel_speed_rad_s"] = {
                n: self.wheel_speed[:, i].tolist() for i, n in enumerate(self.wheels)
            }
        return out

    def _purpose_key(self) -> dict:
        """The file's ``purpose`` key, left out where it is the default."""
        return {} if self.purpose == PURPOSES[0] else {"purpose": self.purpose}

    def save(self, path) -> Path:
        """Write ``.toml`` or ``.json`` (by suffix); returns the path."""
        path = Path(path)
        if path.suffix == ".json":
            path.write_text(json.dumps(self.to_dict(), indent=1) + "\n", encoding="utf-8")
        elif path.suffix == ".toml":
            path.write_text(self.to_toml(), encoding="utf-8")
        else:
            raise ScheduleError(f"{path}: schedule files end in .toml or .json")
        return path

    def to_toml(self) -> str:
        """The schedule as TOML text (numbers with 17 significant digits)."""

        def arr(x):
            return "[" + ", ".join(repr(float(v)) for v in x) + "]"

        lines = ["[schedule]", f"name = {json.dumps(self.name)}", f"t_s = {arr(self.t)}"]
        lines += [f"{k} = {json.dumps(v)}" for k, v in self._purpose_key().items()] + [""]
        lines.append("[rest_length_m]")
        lines += [f"{n} = {arr(self.rest_length[:, i])}" for i, n in enumerate(self.names)]
        if self.wheels:
            lines += ["", "[wheel_speed_rad_s]"]
            lines += [f"{n} = {arr(self.wheel_speed[:, i])}" for i, n in enumerate(self.wheels)]
        return "\n".join(lines) + "\n"


def schedule_from_dict(data: dict, source: str = "<schedule>") -> Schedule:
    """Validate file data (see the module docstring); errors name ``source`` and the key."""

    def fail(key, what):
        raise ScheduleError(f"{source}: {key}: {what}")

    if not isinstance(data, dict):
        fail("<root>", "must be a table")
    for key in data:
        if key not in ("schedule", "rest_length_m", "wheel_speed_rad_s"):
            fail(key, "unknown key (allowed: schedule, rest_length_m, wheel_speed_rad_s)")
    head = data.get("schedule")
    if not isinstance(head, dict):
        fail("schedule", "missing table")
    for key in head:
        if key not in ("name", "t_s", "purpose"):
            fail(f"schedule.{key}", "unknown key (allowed: name, t_s, purpose)")
    name = head.get("name", Path(source).stem)
    if not isinstance(name, str):
        fail("schedule.name", "must be a string")
    purpose = head.get("purpose", PURPOSES[0])
    if purpose not in PURPOSES:
        fail("schedule.purpose", f"must be one of {', '.join(PURPOSES)}, got {purpose!r}")
    t = _numbers(head.get("t_s"), "schedule.t_s", fail)
    wheels = data.get("wheel_speed_rad_s", {})
    if not isinstance(wheels, dict):
        fail("wheel_speed_rad_s", "must be a table of wheel-speed arrays")
    strings = data.get("rest_length_m", {} if wheels else None)
    if not isinstance(strings, dict) or not (strings or wheels):
        fail("rest_length_m", "missing table of rest-length arrays")
    cols = _columns(strings, "rest_length_m", t.size, fail)
    for key, col in zip(strings, cols, strict=True):
        if np.any(col < 0.0):
            fail(f"rest_length_m.{key}[{int(np.argmax(col < 0.0))}]", "negative rest length")
    speeds = _columns(wheels, "wheel_speed_rad_s", t.size, fail)
    bad = np.flatnonzero(np.diff(t) <= 0.0)
    if bad.size:
        fail(f"schedule.t_s[{bad[0] + 1}]", "times must increase strictly")
    return Schedule(
        tuple(strings),
        t,
        _stack(cols, t.size),
        name,
        tuple(wheels),
        _stack(speeds, t.size),
        purpose,
    )


def _stack(cols: list[np.ndarray], size: int) -> np.ndarray:
    return np.column_stack(cols) if cols else np.zeros((size, 0))


def _columns(table: dict, key: str, size: int, fail) -> list[np.ndarray]:
    """The arrays of ``table`` (one per member), each checked to have ``size`` numbers."""
    cols = []
    for member, values in table.items():
        col = _numbers(values, f"{key}.{member}", fail)
        if col.size != size:
            fail(f"{key}.{member}", f"has {col.size} values, t_s has {size}")
        cols.append(col)
    return cols


def _numbers(value, key, fail) -> np.ndarray:
    if not isinstance(value, list) or not value:
        fail(key, "must be a non-empty array of numbers")
    for i, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            fail(f"{key}[{i}]", f"must be a finite number, got {v!r}")
    return np.array(value, float)


def load_schedule(path) -> Schedule:
    """Read a schedule file (``.toml`` or ``.json``).

    Raises
    ------
    ScheduleError
        The file cannot be read or parsed, or a key is missing, unknown or invalid.
    """
    path = Path(path)
    try:
        text = read_text(path)
    except TextFileError as exc:
        raise ScheduleError(str(exc)) from None
    try:
        data = json.loads(text) if path.suffix == ".json" else tomllib.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ScheduleError(f"{path}: cannot parse: {exc}") from None
    return schedule_from_dict(data, path.name)
