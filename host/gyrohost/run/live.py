"""The live view of a run (``gyrotens run --live``): the channels of the run's MCAP file (every
log stream and the 3D scenes, :mod:`gyrohost.run.foxglove`) served while the run goes, over a
Foxglove WebSocket server on localhost, with the ``foxglove-sdk`` package (the optional extra
``live``: ``pip install 'gyrotensegrity[live]'``).

Foxglove connects to ``ws://127.0.0.1:PORT`` (Open connection, Foxglove WebSocket); a client
sees the channels open from then on and every message logged after it subscribed.
"""

from gyrohost.run.foxglove import LogChannels

from .errors import LiveUnavailable

DEFAULT_PORT = 8765
"""Foxglove's default WebSocket port."""


class LiveView:
    """A Foxglove WebSocket server of one run's rows (a log sink, :mod:`gyrohost.run.log`).

    The server starts here, before the run, so its address can be printed first.

    Parameters
    ----------
    scene : gyrotensegrity.Scene or None
        The run's scene, for the 3D scene channels.
    port : int
        TCP port on localhost (0: a free one, see :attr:`port`).

    Raises
    ------
    LiveUnavailable
        ``foxglove-sdk`` is not installed, or the server cannot listen on ``port``.
    """

    name = "live view"

    def __init__(self, scene=None, port: int = DEFAULT_PORT, host: str = "127.0.0.1"):
        try:
            import foxglove
        except ImportError:
            raise LiveUnavailable(
                "--live needs the foxglove-sdk package: pip install 'gyrotensegrity[live]'"
            ) from None
        self._foxglove = foxglove
        self.scene, self.host = scene, host
        self._context = foxglove.Context()  # our channels go to our server only
        try:
            self._server = foxglove.start_server(
                name="gyrotens", host=host, port=port, context=self._context
            )
        except RuntimeError as exc:
            raise LiveUnavailable(f"live view: cannot listen on {host}:{port}: {exc}") from None
        self.port = self._server.port
        self.channels = None
        self._channels: dict = {}

    @property
    def url(self) -> str:
        """The WebSocket address to open in Foxglove."""
        return f"ws://{self.host}:{self.port}"

    def start(self, folder, meta: dict) -> None:
        """Message times from the log's creation on (``meta["created_unix_s"]``)."""
        self.channels = LogChannels(meta["created_unix_s"], self.scene)

    def open(self, name: str, columns, text_columns=(), description: str = "") -> None:
        """Advertise the channels of stream ``name``."""
        fg = self._foxglove
        for spec in self.channels.open(name, columns, text_columns, description):
            schema = fg.Schema(name=spec.schema_name, encoding="jsonschema",
                               data=spec.schema_bytes())  # fmt: skip
            self._channels[spec.topic] = fg.Channel(
                spec.topic, schema=schema, message_encoding="json", context=self._context
            )

    def write(self, name: str, values, texts=None) -> None:
        """Send one row of stream ``name`` (and its scene update) to every subscriber;
        ``texts``: the row as the CSV has it, if formatted."""
        for topic, t_ns, data in self.channels.messages(name, values, texts):
            self._channels[topic].log(data, log_time=t_ns)

    def close(self) -> None:
        """Stop the server (idempotent)."""
        if self._server is not None:
            server, self._server = self._server, None
            server.stop()
