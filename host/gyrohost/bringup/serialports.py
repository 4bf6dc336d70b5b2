"""Serial ports of this machine: which exist, who may open them, how the kernel drives them.

Nothing here opens a port: opening the Mega's port raises DTR and resets the board, so the checks
made before a run (:func:`check_ports`) read the file system only. Those checks are Linux's and
macOS's (device files, owner groups, sysfs); on Windows a ``COMn`` port has no file to check and
pyserial's own error names the port when it cannot be opened.
"""

import os
import stat
from dataclasses import dataclass
from pathlib import Path

from .errors import PortAccessError

BY_ID = Path("/dev/serial/by-id")
"""Links named after each USB-serial adapter (vendor, product, serial number): stable paths."""

SYS = Path("/sys")
"""Where sysfs is mounted (tests point the checks at a tree of their own)."""


@dataclass(frozen=True)
class PortInfo:
    """One serial port.

    Attributes
    ----------
    device : str
        The device path (``/dev/ttyUSB0``, a pty path given on the command line).
    by_id : str
        Its ``/dev/serial/by-id`` link, ``""`` when it has none (not USB, a pty).
    vid_pid : str
        USB vendor and product, ``"0403:6014"``; ``""`` when not USB.
    description : str
        What the kernel or the adapter calls it (``"FT232H"``), ``""`` when nothing.
    """

    device: str
    by_id: str = ""
    vid_pid: str = ""
    description: str = ""

    @property
    def stable_path(self) -> str:
        """The path to write into a configuration: the by-id link if there is one."""
        return self.by_id or self.device


def by_id_link(device: str, by_id_dir: Path = BY_ID) -> str:
    """The ``/dev/serial/by-id`` link resolving to ``device``, ``""`` if none."""
    if not by_id_dir.is_dir():
        return ""
    target = os.path.realpath(device)
    for link in sorted(by_id_dir.iterdir()):
        if os.path.realpath(link) == target:
            return str(link)
    return ""


def list_ports(extra: tuple[str, ...] = ()) -> list[PortInfo]:
    """Every serial port pyserial finds (USB first) and the ``extra`` paths (ptys, ...).

    ``/dev/ttyS*`` ports without hardware behind them (pyserial reports no hardware id) are left
    out: a PC lists dozens of them.
    """
    from serial.tools import list_ports as pyserial_ports

    found = []
    for p in pyserial_ports.comports():
        if p.vid is None and p.hwid in ("n/a", "") and p.device not in extra:
            continue
        vid_pid = f"{p.vid:04x}:{p.pid:04x}" if p.vid is not None else ""
        description = "" if p.description in ("n/a", None) else p.description
        found.append(PortInfo(p.device, by_id_link(p.device), vid_pid, description))
    known = {os.path.realpath(p.device) for p in found}
    for path in extra:
        if os.path.realpath(path) not in known:
            found.append(PortInfo(path, by_id_link(path), "", ""))
    return sorted(found, key=lambda p: (p.vid_pid == "", p.device))


def dialout_fix(group: str) -> str:
    """How to get the rights of ``group`` (the owner group of serial devices, ``dialout``)."""
    return f"sudo usermod -aG {group} $USER, then log out and back in"


def access_problem(
    path: str, uid: int | None = None, groups: tuple[int, ...] | None = None
) -> str | None:
    """Why ``path`` cannot be opened for reading and writing, or None if it can.

    Parameters
    ----------
    path : str
    uid, groups : optional
        The user and group ids to check for (default: this process's).

    Returns
    -------
    str or None
        ``"no such device"`` (with advice for ``/dev/rfcomm*``) or the permission and its fix;
        None where ports are no files (Windows).
    """
    if os.name != "posix":
        return None
    try:
        st = os.stat(path)
    except FileNotFoundError:
        if Path(path).name.startswith("rfcomm"):
            return "no such device (the Bluetooth IMU is not bound: see docs/bring-up.md)"
        return "no such device (unplugged? 'gyrotens ports' lists the ports found)"
    except OSError as exc:
        return f"cannot stat: {exc}"
    uid = os.getuid() if uid is None else uid
    groups = tuple(os.getgroups()) + (os.getgid(),) if groups is None else groups
    if uid == 0:
        return None
    if st.st_uid == uid:
        allowed = st.st_mode & stat.S_IRUSR and st.st_mode & stat.S_IWUSR
    elif st.st_gid in groups:
        allowed = st.st_mode & stat.S_IRGRP and st.st_mode & stat.S_IWGRP
    else:
        allowed = st.st_mode & stat.S_IROTH and st.st_mode & stat.S_IWOTH
    if allowed:
        return None
    group = _group_name(st.st_gid)
    if st.st_gid not in groups and st.st_mode & stat.S_IRGRP and st.st_mode & stat.S_IWGRP:
        return f"permission denied (you are not in the group '{group}': {dialout_fix(group)})"
    return f"permission denied (mode {stat.filemode(st.st_mode)}, group '{group}')"


def _group_name(gid: int) -> str:
    import grp  # POSIX only: imported where a POSIX file's group is named

    try:
        return grp.getgrgid(gid).gr_name
    except KeyError:
        return str(gid)


def check_ports(ports: dict[str, str], where: str = "") -> None:
    """Refuse ports that are missing or not readable and writable, every one named at once.

    Parameters
    ----------
    ports : dict
        Configuration key -> port (``{"imu.port": "/dev/rfcomm0", ...}``).
    where : str
        The configuration file, prefixed to each line.

    Raises
    ------
    PortAccessError
        One line per port at fault: ``FILE: key 'imu.port' = /dev/rfcomm0: no such device ...``.
    """
    lines = [
        f"{where + ': ' if where else ''}key '{key}' = {port}: {problem}"
        for key, port in ports.items()
        if (problem := access_problem(port)) is not None
    ]
    if lines:
        raise PortAccessError("cannot open the devices:\n  " + "\n  ".join(lines))


def latency_timer_path(device: str, sys_root: Path = SYS) -> Path:
    """The FTDI latency timer file of ``device`` (its real tty name under usb-serial)."""
    name = Path(os.path.realpath(device)).name
    return sys_root / "bus" / "usb-serial" / "devices" / name / "latency_timer"


def latency_timer_ms(device: str, sys_root: Path = SYS) -> int | None:
    """The FTDI latency timer of ``device``, ms; None when it has none (not an FTDI adapter)."""
    try:
        return int(latency_timer_path(device, sys_root).read_text().strip())
    except (OSError, ValueError):
        return None


def latency_timer_fix(device: str, sys_root: Path = SYS) -> str:
    """The command that sets the latency timer of ``device`` to 1 ms (until unplugged; the udev
    rule in tools/udev/99-gyrotens.rules makes it permanent)."""
    return f"echo 1 | sudo tee {latency_timer_path(device, sys_root)}"


def rfcomm_bound(device: str, sys_root: Path = SYS) -> bool:
    """``/dev/rfcommN`` is bound (``rfcomm bind`` made the tty; it connects on open)."""
    return (sys_root / "class" / "tty" / Path(device).name).exists()
