"""One process at a time on a serial port (gyrohost.drivers.portlock): a second process is
refused with the holder's PID and command line, a dead holder's lock is taken over, and a
program that opened the device exclusively keeps it too."""

import os
import subprocess
import sys
import textwrap

import pytest

from gyrohost.drivers.errors import PortBusyError
from gyrohost.drivers.portlock import LockedSerial, PortClaim, exclusive_serial, lock_path

HOLD = textwrap.dedent(
    """
    import sys
    from gyrohost.drivers.portlock import LockedSerial
    port = LockedSerial(sys.argv[1], 115200)
    print("holding", flush=True)
    sys.stdin.read()
    port.close()
    """
)


@pytest.fixture
def pty_path():
    """The slave side of a fresh pseudo-terminal, a serial port without hardware."""
    master, slave = os.openpty()
    path = os.ttyname(slave)
    yield path
    os.close(slave)
    os.close(master)


def test_a_second_process_is_refused_naming_the_holder_and_gets_the_port_once_it_is_free(
    pty_path, tmp_path
):
    script = tmp_path / "hold.py"
    script.write_text(HOLD)
    holder = subprocess.Popen(
        [sys.executable, str(script), pty_path, "--marker"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline() == "holding\n"
        with pytest.raises(PortBusyError) as refused:
            LockedSerial(pty_path, 115200)
        message = str(refused.value)
        assert f"{pty_path} is in use by PID {holder.pid} (" in message
        assert "--marker" in message and str(lock_path(pty_path)) in message
        assert "\n" not in message
    finally:
        holder.communicate("", timeout=30)
    assert holder.returncode == 0
    assert not lock_path(pty_path).exists()  # removed by its holder
    LockedSerial(pty_path, 115200).close()


def test_a_lock_file_left_by_a_dead_process_is_taken_over(pty_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)  # fmt: skip
    path = lock_path(pty_path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"{dead.stdout.strip()}\nan old run that was killed\n")
    with LockedSerial(pty_path, 115200):
        assert path.read_text().splitlines()[0] == str(os.getpid())
    assert not path.exists()


def test_claims_in_one_process_nest_and_the_lock_goes_with_the_last(pty_path):
    outer = PortClaim(pty_path)
    inner = PortClaim(pty_path)
    inner.release()
    inner.release()  # idempotent: the outer claim still holds
    assert lock_path(pty_path).exists()
    outer.release()
    assert not lock_path(pty_path).exists()


def test_a_device_opened_exclusively_elsewhere_is_refused_without_a_lock_file(pty_path):
    other = exclusive_serial(pty_path, 115200)  # as a program that knows no lock files
    try:
        with pytest.raises(PortBusyError, match="another program .*opened the device exclusive"):
            LockedSerial(pty_path, 115200)
        assert not lock_path(pty_path).exists()  # the refused claim was released
    finally:
        other.close()
