"""MCAP files of run logs, with the ``mcap`` library: written beside the CSV streams while a run
goes (``run.mcap`` in the log folder), or made from a log folder afterwards
(``gyrotens export LOG --mcap``).

One channel per stream and one per 3D scene (:mod:`gyrohost.run.foxglove`); one message per
CSV row. The file is written without chunks or compression, each message as its row is, and
flushed to the file at least every :data:`FLUSH_PERIOD_S` (a flush per message would double the
loop's system calls), so a run stopped at any point leaves its rows in the file; the summary
and footer (message counts, channel index) come when the log closes, which the safe state does
on every exit a Python process survives (Ctrl-C, SIGTERM, faults). A killed process leaves a file
without them (``mcap recover`` or Foxglove read it; the ``mcap`` Python reader stops at its end
with ``EndOfFile``); :func:`export_mcap` makes a whole one from the CSV streams.
"""

import time
from collections.abc import Callable
from pathlib import Path

from mcap.writer import CompressionType, Writer

from gyrohost.resources import ResourceError, resolve
from gyrohost.run.foxglove import LogChannels
from gyrohost.run.log import read_meta, read_streams
from gyrotensegrity import SceneError, __version__, load_scene

MCAP_NAME = "run.mcap"
FLUSH_PERIOD_S = 0.05
"""Longest time a written message waits in the buffer before it goes to the file, s."""


class McapSink:
    """Every row of a :class:`~gyrohost.run.log.RunLog` into an MCAP file.

    Parameters
    ----------
    scene : gyrotensegrity.Scene or None
        The run's scene, for the 3D scene channels (None: none).
    path : path, optional
        The file (default ``run.mcap`` in the log folder).
    """

    def __init__(self, scene=None, path=None):
        self.scene = scene
        self.path = None if path is None else Path(path)
        self.name = MCAP_NAME if path is None else self.path.name
        self._file = self._writer = self.channels = None
        self._ids: dict[str, int] = {}
        self._flushed_s = 0.0

    def start(self, folder: Path, meta: dict) -> None:
        """Create the file (it must not exist) for the log in ``folder`` created at
        ``meta["created_unix_s"]``."""
        self.path = self.path or Path(folder) / MCAP_NAME
        self.channels = LogChannels(meta["created_unix_s"], self.scene)
        self._file = open(self.path, "xb")
        self._writer = Writer(self._file, use_chunking=False, compression=CompressionType.NONE)
        self._writer.start(profile="", library=f"gyrotens {__version__}")
        self._file.flush()

    def open(self, name: str, columns, text_columns=(), description: str = "") -> None:
        """Register the channels of stream ``name``."""
        for spec in self.channels.open(name, columns, text_columns, description):
            schema = self._writer.register_schema(
                name=spec.schema_name, encoding="jsonschema", data=spec.schema_bytes()
            )
            self._ids[spec.topic] = self._writer.register_channel(
                topic=spec.topic, message_encoding="json", schema_id=schema
            )
        self._file.flush()

    def write(self, name: str, values, texts=None) -> None:
        """Write one row of stream ``name`` (and its scene update); flush if the last flush is
        :data:`FLUSH_PERIOD_S` old. ``texts``: the row as the CSV has it, if formatted."""
        for topic, t_ns, data in self.channels.messages(name, values, texts):
            self._writer.add_message(self._ids[topic], t_ns, data, t_ns)
        now = time.monotonic()
        if now - self._flushed_s >= FLUSH_PERIOD_S:
            self._file.flush()
            self._flushed_s = now

    def close(self) -> None:
        """Write the summary and footer and close the file (idempotent)."""
        if self._file is None:
            return
        file, self._file = self._file, None
        try:
            self._writer.finish()
        finally:
            file.close()


def scene_of(meta: dict, folder, warn: Callable[[str], None] | None = None):
    """The scene a log names (``meta.json`` ``scene``: a path or a shipped name), or None if
    it cannot be loaded (said so to ``warn``)."""
    try:
        return load_scene(resolve("scene", str(meta.get("scene"))))
    except (ResourceError, SceneError, OSError) as exc:
        if warn is not None:
            warn(f"{folder}: scene {meta.get('scene')!r} not loaded ({exc}); no 3D scene")
        return None


def export_mcap(folder, out=None, warn: Callable[[str], None] | None = None) -> Path:
    """Write the MCAP file of the log ``folder`` from its CSV streams; returns its path.

    Rows go in time order across streams (a row without a time first); unreadable rows are
    skipped and streams missing are left out, each said to ``warn``
    (:func:`gyrohost.run.log.read_stream`). ``out`` (default ``run.mcap`` in ``folder``) is
    replaced whole: the file is written beside it and renamed.

    Raises
    ------
    LogError
        ``folder`` is not a log folder, or (without ``warn``) a stream cannot be read.
    """
    folder = Path(folder)
    meta = read_meta(folder)
    out = Path(out) if out is not None else folder / MCAP_NAME
    streams = read_streams(folder, meta["streams"], warn)
    order = sorted(
        (_sort_time(rows, i), k, i)
        for k, rows in enumerate(streams.values())
        for i in range(len(rows))
    )
    tmp = out.with_name(out.name + ".tmp")
    tmp.unlink(missing_ok=True)
    sink = McapSink(scene_of(meta, folder, warn), tmp)
    try:
        sink.start(folder, meta)
        for name, rows in streams.items():
            schema = meta["streams"][name]
            sink.open(name, rows.dtype.names, schema.get("text_columns", ()),
                      schema.get("description", ""))  # fmt: skip
        names = list(streams)
        for _, k, i in order:
            sink.write(names[k], tuple(streams[names[k]][i]))
        sink.close()
        tmp.replace(out)
    finally:
        sink.close()
        tmp.unlink(missing_ok=True)
    return out


def _sort_time(rows, i: int) -> float:
    """``t_s`` of row ``i``; -inf for a row without a time (NaN, or no ``t_s`` column)."""
    t = float(rows["t_s"][i]) if "t_s" in rows.dtype.names else float("nan")
    return t if t == t else float("-inf")
