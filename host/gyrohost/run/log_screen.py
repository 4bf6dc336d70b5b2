"""Rows of a logged input stream that must not be fused, found and counted before replay or
identify hand the stream to the filter or the fit.

A log damaged on disk, edited by hand or written by another tool can hold rows that read as
numbers but are not samples: a value that is not finite (NaN, inf), a row whose time runs
backwards (rows copied or appended twice), a row that repeats an earlier one (the same time and
the same values). Each is left out and counted per stream; one warning per stream and kind names
the file and the rows. The header must be the columns ``meta.json`` declares for the stream, in
their order: swapped or missing columns would put one quantity in another's place, so such a
stream is left out whole, as is one without a row.

Equal times alone are no fault: the IMU's samples of one read share its arrival stamp.
"""

import math
from collections.abc import Callable, Sequence
from pathlib import Path

from .errors import LogError

KINDS = {
    "unreadable": "that cannot be read",
    "non_finite": "with a value that is not finite (NaN, inf)",
    "backwards": "whose time runs backwards",
    "repeated": "repeating the row before at the same time",
}
"""Kinds of rows left out -> how a warning describes them (unreadable rows are warned about one
by one as they are read, :func:`gyrohost.run.log.read_stream`)."""

SHOWN_RANGES = 8
"""Row ranges a warning lists; the rest are counted."""


class StreamScreen:
    """The checks of one stream's rows, in file order; keeps the row numbers left out per kind.

    Parameters
    ----------
    path : Path
        The stream's file (named in warnings).
    header, columns : sequence of str
        The file's header and the columns ``meta.json`` declares.
    text : set of str
        Columns holding words (not checked for finite values).
    """

    def __init__(self, path: Path, header: Sequence[str], columns: Sequence[str], text):
        self.path = path
        self._check_header(list(header), list(columns))
        self.rows = 0
        self.left_out: dict[str, list[int]] = {kind: [] for kind in KINDS}
        self.first_value: dict[str, str] = {}  # non_finite: the first bad column and value
        self._numeric = [(i, c) for i, c in enumerate(header) if c not in text]
        self._t = header.index("t_s") if "t_s" in header else None
        self._last_t = -math.inf
        self._last_line: str | None = None

    def _check_header(self, header: list[str], columns: list[str]) -> None:
        if header == columns:
            return
        missing = [c for c in columns if c not in header]
        extra = [c for c in header if c not in columns]
        if missing or extra:
            what = "; ".join(
                part
                for part in (
                    f"missing {', '.join(map(repr, missing))}" if missing else "",
                    f"not declared {', '.join(map(repr, extra))}" if extra else "",
                )
                if part
            )
        else:
            moved = [c for c, d in zip(header, columns, strict=True) if c != d]
            what = f"columns {', '.join(map(repr, moved))} swapped"
        raise LogError(f"{self.path}: header differs from meta.json's columns ({what})")

    def unreadable(self, row: int) -> None:
        """Row ``row`` (1-based line number) could not be read."""
        self.rows += 1
        self.left_out["unreadable"].append(row)

    def keep(self, row: int, line: str, fields: Sequence[str]) -> bool:
        """Whether the readable row ``row`` (its ``line`` split into ``fields``) may be fused;
        if not, it is counted under its kind."""
        self.rows += 1
        kind = self._fault(line, fields)
        if kind is not None:
            self.left_out[kind].append(row)
            return False
        if self._t is not None:
            self._last_t = float(fields[self._t])
        self._last_line = line
        return True

    def _fault(self, line: str, fields: Sequence[str]) -> str | None:
        for i, column in self._numeric:
            if not math.isfinite(float(fields[i])):
                self.first_value.setdefault("non_finite", f"{column!r}: {fields[i]!r}")
                return "non_finite"
        if self._t is None:
            return None
        t = float(fields[self._t])
        if t < self._last_t:
            return "backwards"
        if t == self._last_t and line == self._last_line:
            return "repeated"
        return None

    @property
    def bad(self) -> int:
        """Rows left out, all kinds."""
        return sum(len(rows) for rows in self.left_out.values())

    def counts(self) -> dict:
        """``rows`` read and the rows left out per kind."""
        return {"rows": self.rows, **{kind: len(rows) for kind, rows in self.left_out.items()}}

    def bad_rows_text(self) -> str:
        """The rows left out, every kind, as ranges (``rows 40-56, 300``)."""
        return rows_text(sorted(r for rows in self.left_out.values() for r in rows))

    def finish(self, warn: Callable[[str], None] | None) -> None:
        """One warning per kind of row left out (unreadable rows were warned about already).

        Raises
        ------
        LogError
            No row at all, or none left to fuse.
        """
        if self.rows == 0:
            raise LogError(f"{self.path}: no rows (header only)")
        for kind, rows in self.left_out.items():
            if rows and kind != "unreadable" and warn is not None:
                first = self.first_value.get(kind)
                why = f", the first in {first}" if first else ""
                warn(
                    f"{self.path}: {len(rows)} of {self.rows} rows {KINDS[kind]} "
                    f"({rows_text(rows)}{why}); not fused"
                )
        if self.bad == self.rows:
            raise LogError(f"{self.path}: none of its {self.rows} rows can be fused")


def rows_text(rows: Sequence[int]) -> str:
    """``rows 3-7, 12`` of sorted row numbers; after :data:`SHOWN_RANGES` ranges, how many
    more rows."""
    ranges: list[list[int]] = []
    for r in rows:
        if ranges and r == ranges[-1][1] + 1:
            ranges[-1][1] = r
        else:
            ranges.append([r, r])
    shown = [f"{a}-{b}" if b > a else f"{a}" for a, b in ranges[:SHOWN_RANGES]]
    rest = sum(b - a + 1 for a, b in ranges[SHOWN_RANGES:])
    word = "row" if len(rows) == 1 else "rows"
    return f"{word} {', '.join(shown)}" + (f" and {rest} more" if rest else "")


class LogScreen:
    """The screens of the streams a command reads from one log: ``streams`` (names to check;
    others are read as they are), then per stream its :class:`StreamScreen`."""

    def __init__(self, streams: Sequence[str]):
        self.names = set(streams)
        self.screens: dict[str, StreamScreen] = {}

    def stream(self, name: str, path: Path, header, schema: dict) -> StreamScreen | None:
        """The screen of stream ``name`` (``None`` if it is not checked)."""
        if name not in self.names:
            return None
        text = set(schema.get("text_columns", ()))
        screen = StreamScreen(path, header, schema.get("columns", header), text)
        self.screens[name] = screen
        return screen

    def counts(self) -> dict:
        """Stream -> :meth:`StreamScreen.counts`, for a summary."""
        return {name: s.counts() for name, s in self.screens.items()}
