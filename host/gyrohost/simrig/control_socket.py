"""How a separate ``gyrotens rig`` process is reached: its ports file and its control socket.

``gyrotens rig`` writes its three pseudo-terminal paths (they change at every start) and the path
of its control socket into a small TOML file, the *ports file*; ``gyrotens run --rig PORTSFILE``
reads the ports from it. Commands (``reset``, ``fault imu silence 2``, ``stats``) reach the rig
over its control socket, a Unix stream socket: one command per line, one answer per command
(the answer's lines, then an empty line). A rig started in the background (``gyrotens rig &``)
never reads its terminal, so it is never stopped for terminal input.

Ports file::

    # gyrotens rig, pid 4242
    imu = "/dev/pts/5"
    wheels = "/dev/pts/6"
    servos = "/dev/pts/7"
    control = "/run/user/1000/gyrotens/rig-ports.sock"
"""

import os
import socket
from dataclasses import dataclass
from pathlib import Path

from gyrohost.drivers.portlock import runtime_dir
from gyrotensegrity.textfile import read_toml

from .errors import ControlError, PortsFileError

DEVICES = ("imu", "wheels", "servos")
ANSWER_END = "\n\n"
"""An answer ends with an empty line (answers may hold several lines)."""


def default_ports_file() -> Path:
    """Where ``gyrotens rig`` writes its ports by default: ``$XDG_RUNTIME_DIR/gyrotens/
    rig-ports.toml`` (a per-user runtime directory), else ``<tmp>/gyrotens-<uid>/
    rig-ports.toml``."""
    return runtime_dir() / "rig-ports.toml"


def control_path(ports_file: Path) -> Path:
    """The control socket of the rig writing ``ports_file``: beside it, suffix ``.sock``."""
    return Path(ports_file).with_suffix(".sock")


@dataclass(frozen=True)
class RigPorts:
    """What a ports file holds: device name -> pty path, and the control socket's path."""

    devices: dict
    control: Path


def write_ports_file(path: Path, devices: dict, control: Path) -> None:
    """Write the ports file (whole or not at all; its folder is created private to the user)."""
    path = Path(path)
    path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    lines = [f"# gyrotens rig, pid {os.getpid()}"]
    lines += [f"{name} = {_toml_string(devices[name])}" for name in DEVICES]
    lines.append(f"control = {_toml_string(control)}")
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")
    tmp.replace(path)


def _toml_string(value) -> str:
    text = str(value)
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def read_ports_file(path: Path) -> RigPorts:
    """Read a ports file written by ``gyrotens rig``.

    Raises
    ------
    PortsFileError
        The file is missing (no rig running?), not TOML, or a key is missing or not a string.
    """
    path = Path(path)
    if not path.is_file():
        raise PortsFileError(
            f"{path}: no ports file (is 'gyrotens rig' running? it prints the path of its "
            "ports file when it starts)"
        )
    data = read_toml(path, PortsFileError)
    for key in (*DEVICES, "control"):
        if not isinstance(data.get(key), str) or not data[key]:
            raise PortsFileError(f"{path}: key '{key}' missing or not a path string")
    return RigPorts({name: data[name] for name in DEVICES}, Path(data["control"]))


class ControlServer:
    """The rig's listening control socket and its connections (polled with ``select``).

    Parameters
    ----------
    path : Path
        Socket path (a stale socket file there is replaced).
    """

    def __init__(self, path: Path):
        self.path = Path(path)
        self.path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        self.path.unlink(missing_ok=True)
        self.listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.listener.bind(str(self.path))
        self.listener.listen(4)
        self._clients: dict[socket.socket, bytes] = {}

    def sockets(self) -> list:
        """Every socket to wait on: the listener and each connection."""
        return [self.listener, *self._clients]

    def handle(self, sock, answer) -> None:
        """Serve ``sock`` (ready to read): accept a connection, or answer each whole line it
        sent with ``answer(line) -> str``. Whatever ``answer`` records is recorded before the
        client reads the answer, so a client that stops the server on it finds it recorded."""
        if sock is self.listener:
            conn, _ = sock.accept()
            self._clients[conn] = b""
            return
        try:
            data = sock.recv(4096)
        except OSError:
            data = b""
        if not data:
            self._drop(sock)
            return
        *lines, rest = (self._clients[sock] + data).split(b"\n")
        self._clients[sock] = rest
        for raw in lines:
            line = raw.decode("utf-8", errors="replace").strip()
            if not line:
                continue
            text = answer(line)
            try:
                sock.sendall((text.rstrip("\n") + ANSWER_END).encode())
            except OSError:
                self._drop(sock)
                break

    def _drop(self, sock) -> None:
        self._clients.pop(sock, None)
        sock.close()

    def close(self) -> None:
        """Close every socket and remove the socket file."""
        for sock in list(self._clients):
            self._drop(sock)
        self.listener.close()
        self.path.unlink(missing_ok=True)


def send_command(path: Path, line: str, timeout_s: float = 10.0) -> str:
    """Send one command line to the rig's control socket at ``path``; returns its answer.

    Raises
    ------
    ControlError
        No rig listens there, or it did not answer within ``timeout_s``.
    """
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.settimeout(timeout_s)
        try:
            sock.connect(str(path))
            sock.sendall(line.strip().encode() + b"\n")
            data = b""
            while not data.endswith(ANSWER_END.encode()):
                chunk = sock.recv(4096)
                if not chunk:
                    break
                data += chunk
        except OSError as exc:
            raise ControlError(f"{path}: rig control socket: {exc.strerror or exc}") from None
    if not data.endswith(ANSWER_END.encode()):
        raise ControlError(f"{path}: the rig closed the connection before answering {line!r}")
    return data.decode("utf-8", errors="replace")[: -len(ANSWER_END)]
