"""What the device commands (``wheels``, ``servos``, ``imu``) share: their ``--config`` and
``--port`` options and how they show their progress."""


def add_device_options(p, device: str) -> None:
    """``--config`` and ``--port`` of a device command (``device``: what the port leads to)."""
    p.add_argument("--config", help="rig configuration (a TOML file or shipped name): its port")
    p.add_argument("--port", help=f"the {device}'s serial port (overrides the configuration's)")


def say(line: str) -> None:
    """One line of a device command's progress, shown at once."""
    print(line, flush=True)
