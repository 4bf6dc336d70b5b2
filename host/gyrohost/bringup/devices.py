"""The device a bring-up command talks to: its port from the rig configuration or the command
line, checked before it is opened, and the wheel board opened and greeted.

Every device command (``gyrotens wheels|servos|imu ...``) takes ``--config`` and ``--port``; the
port given wins over the configuration's. A missing or unreadable port is the user's input to
fix (:class:`SetupInputError`), found before anything is sent.
"""

from contextlib import contextmanager
from dataclasses import dataclass, replace

from gyrohost.config import RigConfig, load_rig_config
from gyrohost.resources import resolve

from . import HELLO_TIMEOUT_S
from .errors import SetupInputError
from .probe import HELLO_PERIOD_S
from .serialports import access_problem

TABLES = {"imu": "imu", "servos": "servos", "wheels": "wheelboard"}
"""Device -> the configuration table holding its ``port``."""


@dataclass(frozen=True)
class Target:
    """What a device command was told: ``--config`` and ``--port`` (either may be None), and how
    long the wheel board's HELLO is repeated for, s."""

    config: str | None
    port: str | None
    hello_timeout_s: float = HELLO_TIMEOUT_S

    def rig(self, device: str) -> RigConfig:
        """The configuration with ``device``'s port set and checked (:func:`with_port`)."""
        return with_port(load_config(self.config), device, self.port)


def load_config(name: str | None) -> RigConfig | None:
    """The rig configuration ``name`` (a TOML file or a shipped name); None when not given.

    Raises
    ------
    ConfigError
        The file is missing or wrong (the message names the file and key).
    """
    if name is None:
        return None
    return load_rig_config(resolve("config", name))


def with_port(config: RigConfig | None, device: str, port: str | None) -> RigConfig:
    """``config`` (the defaults when None) with ``device``'s port set to ``port`` when given;
    the port is then checked.

    Raises
    ------
    SetupInputError
        Neither a configuration nor a port was given, or the port cannot be opened.
    """
    if config is None and port is None:
        raise SetupInputError("give --config FILE (its port) or --port PORT")
    config = config or RigConfig(source="--port")
    table = TABLES[device]
    if port is not None:
        config = replace(config, **{table: replace(getattr(config, table), port=port)})
    where = "--port" if port is not None else f"{config.source}: key '{table}.port'"
    checked_port(getattr(config, table).port, where)
    return config


def checked_port(path: str, where: str = "--port") -> str:
    """``path`` when it can be opened for reading and writing (``where`` names its origin).

    Raises
    ------
    SetupInputError
        It cannot (missing, no permission: the message says why and how to fix it).
    """
    problem = access_problem(path)
    if problem is not None:
        raise SetupInputError(f"{where} {path}: {problem}")
    return path


@contextmanager
def wheel_board(port: str, hello_timeout_s: float = HELLO_TIMEOUT_S, reply_timeout_s: float = 3.0):
    """A connected :class:`~gyrohost.drivers.wheelboard.WheelBoard` on ``port``, closed (all
    wheels stopped) on leaving. Opening a Mega's port resets it and its bootloader ignores
    frames, so HELLO is repeated for ``hello_timeout_s``.

    Raises
    ------
    SetupInputError
        pyserial cannot open the port.
    WheelBoardTimeout
        No HELLO reply in ``hello_timeout_s``.
    """
    from gyrohost.drivers.wheelboard import WheelBoard

    try:
        board = WheelBoard(port, reply_timeout_s=HELLO_PERIOD_S, boot_window_s=hello_timeout_s)
    except OSError as exc:  # pyserial's SerialException is an OSError
        raise SetupInputError(f"cannot open {port}: {exc}") from None
    try:
        board.connect()  # HELLO repeated through the boot window
        board.reply_timeout_s = reply_timeout_s
        yield board
    finally:
        board.close()
