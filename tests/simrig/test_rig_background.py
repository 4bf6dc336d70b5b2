"""``gyrotens rig`` with standard input that is not a terminal (as ``gyrotens rig &`` or under a
supervisor): it keeps serving, answers on its control socket, writes its ports file, and
``gyrotens run --rig PORTSFILE`` runs on it; that run has no truth, and its figures and summary
say "estimate" only."""

import re
import select
import shlex
import signal
import subprocess
import sys
import threading
import time

import matplotlib.figure
import numpy as np
import pytest
from rig_host import start_rig

from gyrohost.cli import main
from gyrohost.commands.run import Progress
from gyrohost.config import load_rig_config
from gyrohost.control.schedule import Schedule
from gyrohost.plots.log import RunData, plot_compare, plot_node_z
from gyrohost.resources import shipped
from gyrohost.run.log import read_meta, read_stream
from gyrohost.simrig.control_socket import (
    ControlServer,
    control_path,
    read_ports_file,
    send_command,
    write_ports_file,
)
from gyrohost.simrig.errors import ControlError
from gyrotensegrity import load_scene


def wait_for_file(path, proc, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not path.exists():
        assert proc.poll() is None, proc.communicate()[1]
        assert time.monotonic() < deadline, f"no {path} within {timeout_s} s"
        time.sleep(0.1)


def short_schedule(tmp_path):
    """s13 1 cm shorter in 0.5 s on the sim-rig scene."""
    scene = load_scene(load_rig_config(shipped("config", "sim-rig")).scene_path)
    l0 = next(s.rest_length(0.0) for s in scene.strings if s.name == "s13")
    s = Schedule(("s13",), [0.0, 0.5], [[l0], [l0 - 0.01]], "short")
    return s.save(tmp_path / "short.toml")


def test_background_rig_serves_a_run_through_its_ports_file(tmp_path, capsys, monkeypatch):
    ports_file = tmp_path / "ports.toml"
    # a pipe never written nor closed: the rig must not read it (nor wait on it)
    proc = start_rig(tmp_path, "--ports-file", str(ports_file), stdin=subprocess.PIPE)
    try:
        wait_for_file(ports_file, proc)
        ports = read_ports_file(ports_file)
        assert set(ports.devices) == {"imu", "wheels", "servos"}
        assert ports.control == ports_file.with_suffix(".sock")
        answer = send_command(ports.control, "fault nothing")
        assert answer.startswith("error: unknown command 'fault nothing'")
        assert main(["rig", "--ports-file", str(ports_file), "--send", "stats"]) == 0
        assert "rates: imu" in capsys.readouterr().out
        # a second rig on the same ports file is refused: the first one still serves it
        assert main(["rig", "--ports-file", str(ports_file)]) == 2
        assert "a rig is already serving there" in capsys.readouterr().err

        log = tmp_path / "log"
        argv = ["run", "--rig", str(ports_file), "--schedule", str(short_schedule(tmp_path))]
        titles, lines = [], []
        original = matplotlib.figure.Figure.suptitle
        monkeypatch.setattr(
            matplotlib.figure.Figure,
            "suptitle",
            lambda fig, text, **kw: titles.append(text) or original(fig, text, **kw),
        )
        # the progress line as a terminal would show it, every tick
        monkeypatch.setattr(Progress, "__call__", lambda self, *a: lines.append(self.line(*a)))
        assert main([*argv, "-o", str(log)]) == 0, capsys.readouterr().err
        out = capsys.readouterr().out
        assert "tilt at the end of the schedule: estimate" in out and "truth" not in out
        schedule = [line for line in lines if "] schedule " in line]
        assert schedule, lines[-5:]
        # D-bar tilt, four wheel speeds near the scene's 74.87 rad/s, the estimator's status
        assert re.search(r"tilt [+-]0\.\d{3} rad \| wheels( [+-]\s*\d+\.\d){4} rad/s \| EKF ",
                         schedule[-1]), schedule[-1]  # fmt: skip
        assert "+74.9" in schedule[-1] or "+74.8" in schedule[-1], schedule[-1]
        # and the body frame's attitude (the scene's [attitude]), degrees
        assert re.search(r"\| EKF \S+ \| roll pitch yaw( \s*[+-]\d+\.\d){3} deg$", schedule[-1])
        assert any(line.endswith("| EKF off") for line in lines if "] spinup " in line)
        meta = read_meta(log)
        assert "truth" not in meta["streams"]
        assert meta["rig_config"]["imu"]["port"] == ports.devices["imu"]
        # the figures that compare with a truth when there is one
        plot_node_z(RunData(log), tmp_path / "fig8.png")
        plot_compare([log], ["a"], tmp_path / "compare.png")
        assert titles == ["dbar-gyro: node z, estimate (Fig. 8)", "node z: EKF estimate"], titles

        assert send_command(ports.control, "reset").startswith("reset")
        assert proc.poll() is None  # still serving after all that
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert f"ports file: {ports_file}" in out and "control: reset: reset" in out
    assert not ports_file.exists() and not ports.control.exists()


def test_a_second_run_on_a_live_rig_is_refused_and_the_first_loses_no_frame(tmp_path, capsys):
    """The second ``run --rig`` on the same ports exits 2 naming the first run's PID and command
    before it sends a byte (no log folder either); the first reads every telemetry frame."""
    ports_file = tmp_path / "ports.toml"
    proc = start_rig(tmp_path, "--ports-file", str(ports_file))
    first = None
    try:
        wait_for_file(ports_file, proc)
        log = tmp_path / "first"
        argv = ["run", "--rig", str(ports_file), "--schedule", str(short_schedule(tmp_path))]
        first = subprocess.Popen([sys.executable, "-m", "gyrohost", *argv, "-o", str(log)],
                                 cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 text=True)  # fmt: skip
        wait_for_text(log / "events.csv", "phase,spinup", first)
        assert main([*argv, "-o", str(tmp_path / "second")]) == 2
        err = capsys.readouterr().err
        assert f"is in use by PID {first.pid} (" in err and "gyrohost run --rig" in err, err
        assert err.count("\n") == 1 and not (tmp_path / "second").exists(), err
        out, first_err = first.communicate(timeout=120)
        assert first.returncode == 0, first_err
        assert "run completed" in out, out
    finally:
        for p in (first, proc):
            if p is not None and p.poll() is None:
                p.kill()
                p.communicate()
    seq = read_stream(log, "wheels")["seq"].astype(int)
    assert len(seq) > 100
    assert np.all(np.diff(seq) % 2**16 == 1), np.flatnonzero(np.diff(seq) % 2**16 != 1)
    links = read_meta(log)["summary"]["links"]["wheels"]
    assert links["sequence_gaps"] == links["crc_errors"] == 0, links


def wait_for_text(path, text: str, proc, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not (path.exists() and text in path.read_text()):
        assert proc.poll() is None, proc.communicate()[1]
        assert time.monotonic() < deadline, f"no {text!r} in {path} within {timeout_s} s"
        time.sleep(0.05)


def test_run_rig_refuses_a_missing_ports_file_and_sim_with_rig(tmp_path, capsys):
    missing = tmp_path / "none.toml"
    assert main(["run", "--rig", str(missing), "-o", str(tmp_path / "a")]) == 2
    assert f"{missing}: no ports file (is 'gyrotens rig' running?" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text('imu = "/dev/pts/1"\n')
    assert main(["run", "--rig", str(bad), "-o", str(tmp_path / "b")]) == 2
    assert "key 'wheels' missing" in capsys.readouterr().err
    assert main(["run", "--sim", "--rig", str(bad), "-o", str(tmp_path / "c")]) == 2
    assert "not both" in capsys.readouterr().err
    assert main(["rig", "--ports-file", str(missing), "--send", "stats"]) == 2
    assert not any((tmp_path / d).exists() for d in "abc")
    capsys.readouterr()
    deep = tmp_path / ("x" * 110) / "ports.toml"  # its socket path is too long for AF_UNIX
    assert main(["rig", "--ports-file", str(deep), "--duration", "1"]) == 2
    assert "cannot open the control socket there" in capsys.readouterr().err
    assert not deep.exists()


def test_ports_file_round_trip_and_control_socket_answers_line_by_line(tmp_path):
    ports_file = tmp_path / 'we"ird\\dir' / "ports.toml"
    devices = {"imu": "/dev/pts/5", "wheels": '/tmp/a "b"', "servos": "/dev/pts/7"}
    server = ControlServer(control_path(ports_file))
    try:
        write_ports_file(ports_file, devices, server.path)
        ports = read_ports_file(ports_file)
        assert ports.devices == devices and ports.control == server.path
        stop = threading.Event()

        def serve():
            while not stop.is_set():
                ready, _, _ = select.select(server.sockets(), [], [], 0.05)
                for sock in ready:
                    server.handle(sock, lambda line: f"{line.upper()}\nsecond line")

        worker = threading.Thread(target=serve)
        worker.start()
        try:
            assert send_command(server.path, "stats") == "STATS\nsecond line"
            assert send_command(server.path, "  reset  ") == "RESET\nsecond line"
        finally:
            stop.set()
            worker.join()
    finally:
        server.close()
    assert not server.path.exists()
    with pytest.raises(ControlError, match="rig control socket"):
        send_command(server.path, "stats", timeout_s=1.0)


def test_rig_as_a_background_job_of_an_interactive_shell_keeps_serving(tmp_path):
    """``gyrotens rig &`` in a shell with job control on a terminal (``script`` gives bash one):
    the job's standard input is the terminal, and reading it would stop the job; ``kill %1``
    ends it as Ctrl-C does."""
    ports_file, out = tmp_path / "ports.toml", tmp_path / "rig.out"
    rig = f"{sys.executable} -m gyrohost rig --ports-file {ports_file}"
    shell = (
        f"set -m; {rig} > {out} 2>&1 & "
        f"for i in $(seq 600); do [ -e {ports_file} ] && break; sleep 0.1; done; sleep 1; "
        f"jobs -l; {rig} --send stats; kill %1; wait %1; echo rig exit $?"
    )
    done = subprocess.run(
        ["script", "-qfc", f"bash --norc -i -c {shlex.quote(shell)}", "/dev/null"],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    text = done.stdout
    assert re.search(r"\[1\]\+ +\d+ Running", text) and "Stopped" not in text, text
    assert "rates: imu" in text and "rig exit 0" in text, text
    assert "stopped by SIGTERM" in out.read_text()  # and cleaned up after itself:
    assert not ports_file.exists() and not ports_file.with_suffix(".sock").exists()
