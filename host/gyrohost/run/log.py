"""Run logs: a folder of append-only CSV streams plus a self-describing ``meta.json``.

Layout of a log folder::

    meta.json        format version, software versions, configuration, scene, stream schemas
    <stream>.csv     one file per stream (``imu``, ``wheels``, ``servos``, ``estimate``, ...)

Every CSV starts with a header line of column names that carry their units (``t_s``,
``omega_x_rad_s``); every row is written whole and flushed at once, so a log survives Ctrl-C or a
crash with at most the row being written lost. Any stream reads in one line::

    np.genfromtxt("imu.csv", delimiter=",", names=True)      # or pandas.read_csv("imu.csv")

Floats are written with 17 significant digits, so a replay reads back bit-identical numbers.

A log hands every row it writes to its *sinks* too (``RunLog(..., sinks=...)``): the MCAP file
of a run (:mod:`gyrohost.run.mcap`), the live view (:mod:`gyrohost.run.live`). A sink has
``start(folder, meta)``, ``open(name, columns, text_columns, description)``, ``write(name,
values, texts)`` (after the CSV row is written whole, so it gets exactly the CSV's rows;
``texts`` the row's values as the CSV has them, or None) and
``close()``; an ``OSError`` of a sink is the log's failure, as a stream's is.
"""

import json
import math
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from .errors import LogError, LogWriteError
from .log_screen import LogScreen

FORMAT = "gyrotens-log"
FORMAT_VERSION = 1
RESERVE_BYTES = 65536
"""Disk space a log holds back (the file ``.reserve``) while it is written and gives up when a
write is refused, so a full disk still takes the summary in ``meta.json`` (about 20 kB)."""


class Stream:
    """One append-only CSV stream with a fixed list of columns, of the log ``log``.

    A write the file system refuses (``OSError``: a full disk) is not raised here: the log
    records it (:attr:`RunLog.failure`) and drops every later row of every stream, so what was
    written stays readable and the writer goes on (the run to its safe state).
    """

    def __init__(self, path: Path, columns: Sequence[str], log: "RunLog"):
        self.path = path
        self.name = path.stem
        self.columns = tuple(columns)
        self.log = log
        self.rows = 0
        self._file = None
        if log.failure is not None:
            return  # the log ends before this stream: nothing is created
        try:
            self._file = open(path, "x", buffering=1, encoding="ascii")  # line-buffered
            self._file.write(",".join(self.columns) + "\n")
        except OSError as exc:
            log.fail(f"{path.name}: {exc}")

    def write(self, *values) -> None:
        """Append one row; ``values`` in column order (numbers, or strings without commas)."""
        if len(values) != len(self.columns):
            raise LogError(
                f"{self.path.name}: row has {len(values)} values, "
                f"columns are {len(self.columns)}: {', '.join(self.columns)}"
            )
        texts = [format_value(v) for v in values]
        line = ",".join(texts) + "\n"
        if self._file is None or self.log.failure is not None:
            return
        try:
            self._file.write(line)
        except OSError as exc:
            self.log.fail(f"{self.path.name}: {exc}")
            return
        self.rows += 1
        if self.columns[0] == "t_s":
            self.log.wrote_at(values[0])
        self.log.forward(self.name, values, texts)

    def close(self) -> None:
        """Close the file; a failing flush is recorded as the log's failure, not raised."""
        if self._file is None:
            return
        file, self._file = self._file, None
        try:
            file.close()
        except OSError as exc:
            self.log.fail(f"{self.path.name}: {exc}")


def format_value(value) -> str:
    """A row value as the CSV writes it: a number in its shortest exact form (``nan``, ``inf``
    as such), an integer or bool as an integer, a string as it is (no commas or newlines)."""
    if isinstance(value, str):
        if "," in value or "\n" in value:
            raise LogError(f"string value {value!r} contains a comma or newline")
        return value
    if isinstance(value, (bool, np.bool_)):
        return str(int(value))
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    x = float(value)
    return "nan" if math.isnan(x) else repr(x)


def check_output_folder(folder: Path | str) -> None:
    """Refuse an output folder that cannot be written, before anything is created.

    ``folder`` may be missing (then its nearest existing parent is checked, and nothing is
    created); if it exists it must be a folder. Writing is tried with an unnamed temporary file,
    so the check leaves nothing behind and sees what the process will see (a read-only file
    system, permissions, a full quota of inodes).

    Raises
    ------
    LogError
        ``folder`` or one of its parents is a file, or the folder cannot be written; one line
        naming the path.
    """
    folder = Path(folder)
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        what = folder if existing == folder else f"{folder}: its parent {existing}"
        raise LogError(f"{what} is a file, not a folder")
    try:
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as exc:
        raise LogError(f"{existing}: cannot write there: {exc.strerror or exc}") from None


def check_new_log_folder(folder: Path | str) -> None:
    """Refuse a folder that cannot take a new log: :func:`check_output_folder`, and a folder that
    already holds a log or any of its files (``meta.json``, a stream's ``.csv``, an ``.mcap``).

    Raises
    ------
    LogError
        One line naming the folder and, if it holds log files, the first few of them.
    """
    folder = Path(folder)
    check_output_folder(folder)
    if folder.is_dir():
        found = sorted(
            p.name
            for p in folder.iterdir()
            if p.name == "meta.json" or p.suffix in (".csv", ".mcap")
        )
        if found:
            listed = ", ".join(found[:3]) + (", ..." if len(found) > 3 else "")
            raise LogError(f"{folder}: already holds a log ({listed}); choose another folder")


class RunLog:
    """A log folder being written. Use as a context manager so streams close on any exit.

    Parameters
    ----------
    folder : path
        Created if missing; must pass :func:`check_new_log_folder`.
    meta : dict
        JSON-serialisable description of the run (configuration, scene, command line, ...).
    sinks : sequence, optional
        Where every row goes too (module docstring), started once the folder exists.

    Attributes
    ----------
    failure : str or None
        The first write the file system refused (file and error), None while all is written;
        from then on no row is written (:class:`Stream`), and :meth:`check` raises.
    last_t_s : float
        ``t_s`` of the last row written whole (NaN before any): where the log ends, s.
    """

    def __init__(self, folder: Path | str, meta: dict, sinks: Sequence = ()):
        self.folder = Path(folder)
        check_new_log_folder(self.folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.meta = {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "created_unix_s": time.time(),
            "streams": {},
            **meta,
        }
        self.streams: dict[str, Stream] = {}
        self.failure: str | None = None
        self.last_t_s = math.nan
        self._reserve = self.folder / ".reserve"
        self._write_meta()
        try:
            with open(self._reserve, "wb") as f:
                f.write(bytes(RESERVE_BYTES))
        except OSError as exc:
            self.fail(f"{self._reserve.name}: {exc}")
        self.sinks: list = []
        for sink in sinks:
            if self._sink_call(sink, "start", self.folder, self.meta):
                self.sinks.append(sink)

    def stream(
        self,
        name: str,
        columns: Sequence[str],
        text_columns: Sequence[str] = (),
        description: str = "",
    ) -> Stream:
        """Open stream ``<name>.csv``; ``columns`` carry units, ``text_columns`` hold words."""
        if name in self.streams:
            raise LogError(f"{self.folder}: stream {name!r} is already open")
        unknown = set(text_columns) - set(columns)
        if unknown:
            raise LogError(f"stream {name!r}: text columns {sorted(unknown)} are not columns")
        s = Stream(self.folder / f"{name}.csv", columns, self)
        self.streams[name] = s
        for sink in self.sinks:
            self._sink_call(sink, "open", name, columns, text_columns, description)
        self.meta["streams"][name] = {
            "columns": list(columns),
            "text_columns": list(text_columns),
            "description": description,
        }
        self._write_meta()
        return s

    def update_meta(self, **items) -> None:
        """Add or replace top-level items of ``meta.json`` (e.g. a summary at the end of a run).

        Raises
        ------
        LogWriteError
            ``meta.json`` could not be written (it keeps its previous content).
        """
        self.meta.update(items)
        self._write_meta()

    def _write_meta(self) -> None:
        tmp = self.folder / "meta.json.tmp"
        text = json.dumps(self.meta, indent=2, default=_json_default) + "\n"
        try:
            with open(tmp, "w", encoding="utf-8") as f:
                f.write(text)
            tmp.replace(self.folder / "meta.json")  # whole or not at all
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            self.fail(f"meta.json: {exc}")
            self.check()

    def forward(self, name: str, values, texts=None) -> None:
        """Hand one row of stream ``name``, written whole, to every sink (``texts``: the
        values as the CSV has them, :func:`format_value`, so a sink need not format again)."""
        for sink in self.sinks:
            self._sink_call(sink, "write", name, values, texts)

    def _sink_call(self, sink, method: str, *args) -> bool:
        """Call a sink; its ``OSError`` (a full disk) is the log's failure, and the sink is
        dropped (closed as far as it goes). Returns whether the call succeeded."""
        try:
            getattr(sink, method)(*args)
            return True
        except OSError as exc:
            self.fail(f"{sink.name}: {exc}")
        if sink in self.sinks:
            self.sinks.remove(sink)
        try:
            sink.close()
        except OSError:
            pass  # the failure is recorded already
        return False

    def fail(self, failure: str) -> None:
        """Record a refused write (the first one is kept); later rows are dropped and the
        reserved space is given up for the summary."""
        self.failure = self.failure or failure
        self._release()

    def _release(self) -> None:
        try:
            self._reserve.unlink(missing_ok=True)
        except OSError:
            pass  # a folder gone read-only: nothing more will be written either

    def wrote_at(self, t_s) -> None:
        """A row stamped ``t_s`` was written whole."""
        t = float(t_s)
        if math.isnan(self.last_t_s) or t > self.last_t_s:
            self.last_t_s = t

    def ends_at(self) -> str:
        """Where the log ends, for the user: ``t = 3.210 s`` (host time of the last row)."""
        if math.isnan(self.last_t_s):
            return "before its first row"
        return f"at t = {self.last_t_s:.3f} s"

    def check(self) -> None:
        """Raise :class:`LogWriteError` if a write failed."""
        if self.failure is not None:
            raise LogWriteError(
                f"{self.folder}: writing the log failed ({self.failure}); the log ends "
                f"{self.ends_at()}"
            )

    def close(self) -> None:
        """Close every stream and sink (a failing close is recorded, not raised)."""
        for s in self.streams.values():
            s.close()
        for sink in list(self.sinks):
            self._sink_call(sink, "close")
        self.sinks = []
        self._release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        """Close; with no other exception under way, a failed write raises
        :class:`LogWriteError` here, so no writer loses rows without knowing."""
        self.close()
        if exc[0] is None:
            self.check()
        return False


def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.generic,)):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"meta item of type {type(obj).__name__} is not JSON-serialisable")


def read_meta(folder: Path | str) -> dict:
    """Read and check ``meta.json`` of a log folder."""
    path = Path(folder) / "meta.json"
    try:
        meta = json.loads(path.read_bytes())
    except FileNotFoundError:
        raise LogError(f"{folder}: not a log folder (no meta.json)") from None
    except OSError as exc:
        raise LogError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise LogError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(meta, dict) or not isinstance(meta.get("streams", {}), dict):
        raise LogError(f"{path}: not a log's meta.json (no table of streams)")
    if meta.get("format") != FORMAT:
        raise LogError(f"{path}: format is {meta.get('format')!r}, expected {FORMAT!r}")
    if meta.get("format_version", 0) > FORMAT_VERSION:
        raise LogError(
            f"{path}: format version {meta['format_version']} is newer than this reader "
            f"({FORMAT_VERSION}); update gyrotens"
        )
    return meta


def read_stream(
    folder: Path | str,
    name: str,
    warn: Callable[[str], None] | None = None,
    screen: LogScreen | None = None,
) -> np.ndarray:
    """Read one stream as a structured array (one field per column).

    A row that cannot be read (a field that is not a number or not ASCII, too few or too many
    fields: a log damaged on disk or cut by a power loss) raises ``LogError`` naming the file,
    row and column; with ``warn`` given the row is skipped and ``warn`` gets that message. A last
    row without its newline (cut short by a crash) is dropped, and said so to ``warn``. With a
    ``screen`` that checks this stream (:mod:`gyrohost.run.log_screen`), rows not to be fused
    are left out and counted there, each kind warned about once.

    Raises
    ------
    LogError
        The stream is not in the log (file or schema missing), the file cannot be read or has no
        header line, or (without ``warn``) a row cannot be read; screened: a header other than
        the declared columns, no rows, or none to fuse.
    """
    path = Path(folder) / f"{name}.csv"
    schema = read_meta(folder).get("streams", {}).get(name)
    if schema is None or not path.exists():
        raise LogError(f"{folder}: no stream {name!r} ({path.name} or its schema missing)")
    text = set(schema.get("text_columns", ()))
    try:
        # A power loss can leave NULs or stray bytes: they become U+FFFD and fail their row only.
        lines = path.read_bytes().decode("ascii", errors="replace").split("\n")
    except OSError as exc:
        raise LogError(f"{path}: cannot read: {exc.strerror or exc}") from None
    header = lines[0].split(",")
    if header == [""]:
        raise LogError(f"{path}: empty (no header line)")
    checks = None if screen is None else screen.stream(name, path, header, schema)
    rows = lines[1:]
    if rows and rows.pop() and warn is not None:
        warn(
            f"{path}: row {len(rows) + 2} cut short (no newline at the end: the run stopped "
            "while writing it); row dropped"
        )
    good = []
    for i, line in enumerate(rows):
        fields = line.split(",")
        problem = _row_problem(fields, header, text)
        if problem is None:
            if checks is None or checks.keep(i + 2, line, fields):
                good.append(fields)
            continue
        if warn is None:
            raise LogError(f"{path}: row {i + 2}{problem}")
        warn(f"{path}: row {i + 2}{problem}; row skipped")
        if checks is not None:
            checks.unreadable(i + 2)
    if checks is not None:
        checks.finish(warn)
    width = {c: max((len(f[j]) for f in good), default=1) for j, c in enumerate(header)}
    dtype = [(c, f"U{max(width[c], 1)}" if c in text else "f8") for c in header]
    out = np.empty(len(good), dtype=dtype)
    for i, fields in enumerate(good):
        out[i] = tuple(f if c in text else float(f) for c, f in zip(header, fields, strict=True))
    return out


def read_streams(
    folder: Path | str,
    names,
    warn: Callable[[str], None] | None = None,
    without: str = "left out",
    screen: LogScreen | None = None,
) -> dict[str, np.ndarray]:
    """The streams ``names`` of a log folder (:func:`read_stream` each, with ``screen``), by
    name.

    Without ``warn`` a stream that cannot be read raises ``LogError``; with it, unreadable rows
    are skipped and a stream that cannot be read at all is left out, said to ``warn`` as
    ``<error>; <without>``.
    """
    out = {}
    for name in names:
        try:
            out[name] = read_stream(folder, name, warn, screen)
        except LogError as exc:
            if warn is None:
                raise
            warn(f"{exc}; {without}")
    return out


def _row_problem(fields: list[str], header: list[str], text: set[str]) -> str | None:
    """What makes a row unreadable (``", column 'c': ..."``), or ``None``."""
    if len(fields) < len(header):
        n = len(fields)
        return f", column {header[n]!r}: missing ({n} fields, the header has {len(header)})"
    if len(fields) > len(header):
        n = len(fields)
        return f", after column {header[-1]!r}: {n} fields, the header has {len(header)}"
    for c, f in zip(header, fields, strict=True):
        if "\ufffd" in f or "\0" in f:
            return f", column {c!r}: bytes that are not ASCII text"
        if c not in text:
            try:
                float(f)
            except ValueError:
                return f", column {c!r}: {f!r} is not a number"
    return None
