"""``gyrotens run`` and ``gyrotens demo`` as a user runs them: Ctrl-C to the whole process group
(the CLI and its simulated rig), refusals with clear messages, the demo's outputs."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from gyrohost.cli import main
from gyrohost.control.schedule import Schedule
from gyrohost.resources import shipped
from gyrohost.run.log import read_meta, read_stream

CONFIG = shipped("config", "sim-rig")
L0 = 0.43105229381822


def schedule_file(tmp_path, end_m, duration_s) -> Path:
    s = Schedule(("s13", "s24"), [0.0, duration_s], [[L0, L0], [end_m, L0]], "cli-test")
    return s.save(tmp_path / "schedule.toml")


def wait_for(path: Path, text: str, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if path.exists() and text in path.read_text():
            return
        time.sleep(0.05)
    raise AssertionError(f"{path}: no {text!r} within {timeout_s} s")


def ctrl_c_run(tmp_path, phase: str, after_s: float = 0.0):
    """``gyrotens run --sim`` in a session of its own, Ctrl-C to its whole group (as a terminal
    sends it: the CLI, its rig and estimator processes) ``after_s`` after ``phase`` began;
    returns (exit status, stdout, stderr, log folder)."""
    log = tmp_path / "log"
    cmd = [sys.executable, "-m", "gyrohost", "run", "--config", str(CONFIG), "--sim"]
    cmd += ["--schedule", str(schedule_file(tmp_path, L0 - 0.1, 2.0)), "-o", str(log)]
    proc = subprocess.Popen(
        cmd, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True
    )
    try:
        deadline = time.monotonic() + 60.0
        while not ((log / "events.csv").exists() and f"phase,{phase}" in
                   (log / "events.csv").read_text()):  # fmt: skip
            assert proc.poll() is None, proc.communicate()[1].decode()
            assert time.monotonic() < deadline, f"no {phase} within 60 s"
            time.sleep(0.02)
        time.sleep(after_s)
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    return proc.returncode, out.decode(), err.decode(), log


def test_ctrl_c_to_the_process_group_ends_in_the_safe_state(tmp_path):
    status, out, err, log = ctrl_c_run(tmp_path, "schedule", 0.3)
    assert status == 130, err
    assert "stopped in the safe state: interrupted (Ctrl-C)" in err
    assert f"log: {log}" in out
    summary = read_meta(log)["summary"]
    assert summary["safe_state"]["wheels_stopped"] and summary["safe_state"]["servos_holding"]
    truth = read_stream(log, "truth")
    assert np.max(np.abs(truth["omega_0_rad_s"])) > 70.0
    assert abs(truth["omega_0_rad_s"][-1]) < 25.0  # ramped down: the rig kept running for it


def test_ctrl_c_during_spin_up_prints_no_traceback_and_the_safe_state_line(tmp_path):
    """Ctrl-C to the group while the wheels spin up: the estimator's child is still starting
    (its interpreter importing) and must not print a KeyboardInterrupt traceback."""
    status, out, err, log = ctrl_c_run(tmp_path, "spinup")
    assert status == 130, err
    assert "Traceback" not in err, err
    assert "stopped in the safe state: interrupted (Ctrl-C)" in err
    assert "gyrotens run: wheels stopped" in err and "; servos holding" in err, err
    assert read_meta(log)["summary"]["safe_state"]["wheels_stopped"]


def test_run_refuses_a_schedule_beyond_the_limits_and_emulated_ports_without_sim(tmp_path, capsys):
    bad = schedule_file(tmp_path, 0.05, 5.0)
    argv = ["run", "--config", str(CONFIG), "--sim", "--schedule", str(bad), "-o", "x"]
    assert main(argv) == 2
    assert "s13: rest length 0.05..0.4311 m outside [0.12, 0.45] m" in capsys.readouterr().err
    assert main(["run", "--config", str(CONFIG), "-o", str(tmp_path / "y")]) == 2
    assert "are 'emulator': add --sim" in capsys.readouterr().err
    assert main(["run", "--config", str(CONFIG), "--schedule", "nope", "--sim"]) == 2
    assert "nope" in capsys.readouterr().err
    assert not (tmp_path / "y").exists()


def test_run_states_the_schedules_duration_and_refuses_one_too_long(tmp_path, capsys):
    """A schedule ending at 1e9 s (a unit slip) is refused before anything starts; the
    duration is stated first, against the limit (RunSettings.max_schedule_s, or
    --max-duration)."""
    endless = Schedule(("s13",), [0.0, 1e9], [[L0], [L0 - 0.01]], "endless").save(
        tmp_path / "endless.toml"
    )
    argv = ["run", "--config", str(CONFIG), "--sim", "--schedule", str(endless)]
    assert main([*argv, "-o", str(tmp_path / "a")]) == 2
    out, err = capsys.readouterr()
    assert out == "schedule endless: 1e+09 s (at most 600 s allowed)\n"
    assert "schedule endless refused, nothing moved: it lasts 1e+09 s, more than the 600 s" in err
    short = schedule_file(tmp_path, L0 - 0.01, 5.0)
    argv = ["run", "--config", str(CONFIG), "--sim", "--schedule", str(short)]
    assert main([*argv, "--max-duration", "2", "-o", str(tmp_path / "b")]) == 2
    assert "it lasts 5 s, more than the 2 s a run may play" in capsys.readouterr().err
    assert main([*argv, "--max-duration", "nan", "-o", str(tmp_path / "c")]) == 2
    assert "--max-duration nan: must be a positive number" in capsys.readouterr().err
    assert not any((tmp_path / d).exists() for d in "abc")


def test_run_without_the_devices_names_every_missing_port_and_leaves_no_log(tmp_path, capsys):
    calibrated = tmp_path / "rig.toml"
    text = shipped("config", "lab-rig").read_text().replace("# CALIBRATE", "# calibrated")
    calibrated.write_text(text)
    log = tmp_path / "log"
    argv = ["run", "--config", str(calibrated), "-o", str(log), "--imu", str(tmp_path / "no-imu")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"key 'imu.port' = {tmp_path / 'no-imu'}: no such device" in err
    assert "key 'wheelboard.port' = /dev/gyrotens-wheels: no such device" in err
    assert "key 'servos.port' = /dev/gyrotens-servos: no such device" in err
    assert "Traceback" not in err and not log.exists()


def test_demo_writes_both_logs_all_figures_and_a_summary(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "-o", str(out), "--duration", "2.0", "--config", str(CONFIG)]) == 0
    printed = capsys.readouterr().out
    assert f"outputs in {out}/" in printed
    for run in ("gyro", "nospin"):
        assert read_meta(out / run)["summary"]["completed"]
        pngs = sorted(p.name for p in (out / run / "plots").glob("*.png"))
        assert pngs == sorted(
            ["fig7-nodes.png", "fig8-node-z.png", "attitude.png", "body-attitude.png",
             "wheels.png", "innovations.png", "loop-jitter.png"]
        )  # fmt: skip
    assert (out / "fig7-spin-vs-nospin.png").stat().st_size > 10_000
    summary = (out / "summary.md").read_text()
    assert "| wheels at 715 rpm |" in summary and "| no spin |" in summary
    assert "loop at 100 Hz" in summary
    assert main(["plot", str(out / "nospin"), "-o", str(tmp_path / "again")]) == 0
    assert len(list((tmp_path / "again").glob("*.png"))) == 7


def test_run_target_tilt_options_are_checked_before_anything_moves(tmp_path, capsys):
    base = ["run", "--config", str(CONFIG), "--sim", "-o", str(tmp_path / "z")]
    assert main([*base, "--schedule", "paper", "--target-tilt", "-0.3"]) == 2
    assert "not both" in capsys.readouterr().err
    assert main([*base, "--closed-loop"]) == 2
    assert "need --target-tilt" in capsys.readouterr().err
    assert main([*base, "--target-tilt", "-0.3", "--duration", "0"]) == 2
    assert "must be positive" in capsys.readouterr().err
    assert not (tmp_path / "z").exists()


def test_run_target_attitude_options_are_checked_before_anything_moves(tmp_path, capsys):
    base = ["run", "--config", str(CONFIG), "--sim", "-o", str(tmp_path / "z")]
    shape = tmp_path / "shape.toml"
    shape.write_text("[rest_length]\ns13 = 0.40\ns99 = 0.4\n")
    pitch = ["--target-attitude", "0,-5,0"]
    cases = [
        (["--target-attitude", "5,0"], "need three numbers"),
        (["--target-attitude", "0,-5,0", "--target-tilt", "-0.1"], "not both"),
        (["--strings-only"], "go with --target-attitude"),
        (["--target-shape", str(shape)], "go with --target-attitude"),
        ([*pitch, "--target-shape", str(tmp_path / "none.toml")], "cannot read"),
        ([*pitch, "--wheels-only", "--target-shape", str(shape)], "a target shape needs"),
        ([*pitch, "--target-shape", str(shape)], "s99 not actuated"),
        # strings alone turn the D-bar only about its momentum (y): a roll is out of reach
        (["--target-attitude", "5,0,0", "--strings-only"], "is out of reach in 4 s (strings)"),
    ]
    for extra, message in cases:
        assert main([*base, *extra]) == 2, extra
        assert message in capsys.readouterr().err, extra
    assert not (tmp_path / "z").exists()
