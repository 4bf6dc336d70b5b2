"""``gyrotens ports`` against the simulated rig's ptys: each device found by its own protocol,
the configuration lines to paste; a port where nothing answers said so."""

import os
import pty
import subprocess
import sys

from gyrohost.bringup.probe import probe
from gyrohost.cli import main
from gyrohost.drivers import wheelproto as wp


def test_ports_identifies_the_three_devices_and_prints_config_lines(rig_ports, capsys):
    paths = [rig_ports[d] for d in ("imu", "wheels", "servos")]
    assert main(["ports", "--hello-timeout", "1.0", "--reply-timeout", "0.2", *paths]) == 0
    out = capsys.readouterr().out
    assert "BWT61CL, " in out and " Hz" in out
    assert f"wheel board firmware 1.0, protocol v{wp.PROTO_VERSION}, 4 wheels" in out
    assert "ID 1 MX-12W, ID 2 MX-12W at 1000000 baud" in out
    pasted = out.split("configuration lines to paste (docs/rig-config.md):\n")[1]
    assert f'[imu]\nport = "{rig_ports["imu"]}"\nbaud = 115200' in pasted
    assert f'[wheelboard]\nport = "{rig_ports["wheels"]}"\nbaud = 1000000' in pasted
    assert f'[servos]\nport = "{rig_ports["servos"]}"\nbaud = 1000000' in pasted


def test_probe_writes_only_hello_and_ping_where_nothing_answers():
    master, slave = pty.openpty()
    try:
        result = probe(
            os.ttyname(slave), imu_window_s=0.2, hello_timeout_s=0.3, reply_timeout_s=0.005
        )
        assert result.device == "" and result.detail.startswith("nothing answered")
        os.set_blocking(master, False)
        sent = os.read(master, 4096)
    finally:
        os.close(master)
        os.close(slave)
    pings = [bytes([0xFF, 0xFF, i, 2, 1, ~(i + 3) & 0xFF]) for i in range(1, 11)]
    rest = sent
    for ping in pings * 2:  # IDs 1..10 at 1 Mbps, then at 57600
        assert ping in rest
        rest = rest.replace(ping, b"", 1)
    frames = [f for f in rest.split(b"\x00") if f]
    assert frames and set(frames) == {wp.encode("HELLO")[:-1]}  # HELLO, repeated; nothing else


def test_a_port_another_process_holds_is_named_and_not_written_to(capsys):
    """A run under way holds the port: ``ports`` says who, exits 2 as for any port it cannot
    probe, and sends it nothing (a HELLO or a PING would reach the device in the middle of the
    run)."""
    master, slave = pty.openpty()
    path = os.ttyname(slave)
    hold = (
        "import sys\nfrom gyrohost.drivers.portlock import PortClaim\n"
        "claim = PortClaim(sys.argv[1])\nprint('held', flush=True)\nsys.stdin.read()\n"
    )
    holder = subprocess.Popen([sys.executable, "-c", hold, path],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)  # fmt: skip
    try:
        assert holder.stdout.readline() == "held\n"
        assert main(["ports", "--hello-timeout", "0.3", "--reply-timeout", "0.05", path]) == 2
    finally:
        holder.communicate("", timeout=30)
    err = capsys.readouterr().err
    assert f"cannot probe {path}: {path} is in use by PID {holder.pid} (" in err, err
    os.set_blocking(master, False)
    try:
        written = os.read(master, 4096)
    except BlockingIOError:
        written = b""
    os.close(master)
    os.close(slave)
    assert written == b""
