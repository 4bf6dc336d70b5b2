"""``gyrotens rig`` in a subprocess with the three drivers on its paths: rates and faults sent
over its control socket."""

import re
import subprocess
import threading
import time

import pytest
from rig_host import exercise, start_rig

from gyrohost.cli import main
from gyrohost.simrig.control_socket import default_ports_file, read_ports_file, send_command

DURATION_S = 6.0


def read_paths(proc) -> dict[str, str]:
    paths = {}
    deadline = time.monotonic() + 30.0
    while len(paths) < 3 and time.monotonic() < deadline:
        line = proc.stdout.readline()
        match = re.match(r"(imu|wheels|servos): (/dev/\S+)$", line.strip())
        if match:
            paths[match[1]] = match[2]
    return paths


def test_gyrotens_rig_serves_all_three_devices_at_their_rates(tmp_path):
    # from any directory: the default configuration is shipped
    proc = start_rig(tmp_path, "--duration", str(DURATION_S), stdin=subprocess.PIPE)
    try:
        paths = read_paths(proc)
        assert set(paths) == {"imu", "wheels", "servos"}, proc.stderr.read()
        host = {}
        worker = threading.Thread(
            target=lambda: host.update(exercise(paths, "sim-rig", DURATION_S - 2.5))
        )
        worker.start()
        time.sleep(1.5)  # the host has its ports open by now
        control = read_ports_file(default_ports_file()).control
        assert send_command(control, "fault imu corrupt 3") == "injected: imu corrupt 3"
        proc.stdin.write("fault nothing\n")  # not a terminal: never read
        proc.stdin.flush()
        worker.join(timeout=30)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert "control: fault imu corrupt 3: injected: imu corrupt 3" in out
    assert "fault nothing" not in out
    rates = re.search(
        r"rates: imu ([\d.]+) samples/s \(([\d.]+) frames/s\), wheels ([\d.]+) telemetry "
        r"frames/s, servos ([\d.]+) packets/s",
        out,
    )
    assert rates, out
    imu, frames, telemetry, servo = map(float, rates.groups())
    # The IMU emulator loses the samples of a stall of the loop longer than its backlog (a
    # loaded CPU); the wheel board catches up its 1 kHz ticks.
    assert 80 <= imu <= 102 and frames == pytest.approx(3 * imu, rel=0.01)
    assert telemetry == pytest.approx(500, rel=0.05)
    assert servo > 10  # the stand-in host reads at up to 50 Hz for most of the run
    truth = r"truth: \d+ steps of 5 ms, .* real-time factor [\d.]+, \d+ late steps .* slipped "
    assert re.search(truth, out), out
    # What the host received matches what the rig says it served.
    assert host["telemetry_s"] == pytest.approx(500, rel=0.15)
    assert 75 <= host["imu_samples_s"] <= 105
    assert host["imu_bad_frames"] >= 1  # the corruption sent to the control socket arrived


def test_gyrotens_rig_user_errors(tmp_path, capsys):
    assert main(["rig", "--config", str(tmp_path / "none.toml")]) == 2
    assert "none.toml: no such file and no shipped config" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text('scene = "missing.toml"\n')
    assert main(["rig", "--config", str(bad)]) == 2
    assert "missing.toml" in capsys.readouterr().err
    assert main(["rig", "--duration", "-1"]) == 2
