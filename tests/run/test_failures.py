"""What a run does when things fail around it, on the simulated rig: the rig process killed
mid-run (a USB unplug), a full disk, SIGTERM and SIGHUP, a wheel-board reset. Every case ends in
the safe state with a summary in ``meta.json`` saying what each step reached, a log readable up
to the fault, and no traceback."""

import errno
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_run_cli import CONFIG as CONFIG_PATH
from test_run_cli import L0, schedule_file, wait_for
from test_runloop import SHORT, events, run, short_schedule

from gyrohost.cli import main
from gyrohost.control.schedule import Schedule
from gyrohost.run import log as runlog
from gyrohost.run import mcap as runmcap
from gyrohost.run.log import read_meta, read_stream

pytestmark = pytest.mark.filterwarnings("error::pytest.PytestUnhandledThreadExceptionWarning")
STEPS = [
    "stop wheels",
    "hold servos",
    "stop readers",
    "close devices",
    "stop estimator",
    "summary",
    "close log",
]


def assert_log(folder) -> dict:
    """Every stream reads back; the summary lists the safe state's steps in order."""
    meta = read_meta(folder)
    for name in meta["streams"]:
        read_stream(folder, name)
    safe = meta["summary"]["safe_state"]
    assert [s["step"] for s in safe["steps"]] == STEPS, safe["steps"]
    return safe


def test_the_rig_process_killed_mid_run_still_ends_in_the_safe_state(tmp_path, capfd):
    """As a USB unplug: every port goes away at once. No step stops the next."""

    def kill(loop, phase, t_s):
        if phase == "schedule" and t_s - loop.t_schedule_s > 0.3 and loop.rig._proc.is_alive():
            loop.rig._proc.kill()
            loop.rig._proc.join(5.0)

    result, folder = run(tmp_path, on_tick=kill)
    assert result.exit_status == 1, result.reason
    safe = assert_log(folder)
    steps = {s["step"]: s for s in safe["steps"]}
    assert not steps["stop wheels"]["ok"] and "unknown" in safe["wheels"]
    assert not safe["wheels_stopped"]
    assert not steps["hold servos"]["ok"]
    assert all(not s["holding"] and "no read-back" in s["why"] for s in safe["servos"].values())
    assert steps["close log"]["ok"]
    assert "Traceback" not in capfd.readouterr().err


class TinyDisk:
    """``open`` of the log modules (CSV, MCAP) on a disk of ``size`` bytes: a write that does not
    fit writes what fits and raises ENOSPC, as a full file system does; deleted files give their
    space back."""

    def __init__(self, folder: Path, size: int):
        self.folder, self.size, self.used = folder, size, 0

    def open(self, path, mode="r", **kwargs):
        return _File(self, open(path, mode, **kwargs))

    def take(self, n: int) -> int:
        """Bytes of ``n`` that fit now."""
        if self.used + n > self.size:  # recount: files may have been removed or replaced
            self.used = sum(p.stat().st_size for p in self.folder.iterdir() if p.is_file())
        return max(min(n, self.size - self.used), 0)


class _File:
    def __init__(self, disk: TinyDisk, file):
        self.disk, self.file = disk, file

    def write(self, data):
        fits = self.disk.take(len(data))
        self.file.write(data[:fits])
        self.file.flush()
        self.disk.used += fits
        if fits < len(data):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return fits

    def flush(self):
        self.file.flush()

    def tell(self):
        return self.file.tell()

    def close(self):
        self.file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def test_a_full_disk_ends_the_run_in_the_safe_state_and_says_where_the_log_ends(
    tmp_path, monkeypatch, capfd
):
    """capfd: the estimator's child writes to the process's stderr, not to ``sys.stderr``."""
    log = tmp_path / "log"
    log.mkdir()
    disk = TinyDisk(log, 700_000)
    monkeypatch.setattr(runlog, "open", disk.open, raising=False)
    monkeypatch.setattr(runmcap, "open", disk.open, raising=False)  # run.mcap on the same disk
    argv = ["run", "--config", str(CONFIG_PATH), "--sim", "-o", str(log)]
    argv += ["--schedule", str(schedule_file(tmp_path, L0 - 0.05, 4.0))]
    assert main(argv) == 1
    err = capfd.readouterr().err
    assert "Traceback" not in err
    assert "LogWriteError" in err and "No space left on device" in err
    assert "gyrotens run: wheels stopped (" in err and "; servos holding" in err, err
    meta = read_meta(log)
    summary = meta["summary"]
    safe = assert_log(log)
    t_end = safe["log_ends_t_s"]
    assert f"the log ends at t = {t_end:.3f} s" in err
    assert summary["reason"].startswith("LogWriteError")
    assert safe["wheels_stopped"] and safe["servos_holding"], safe
    steps = {s["step"]: s["ok"] for s in safe["steps"]}
    assert steps == {**dict.fromkeys(STEPS, True), "close log": False}
    for name in meta["streams"]:  # rows up to the fault, none after
        rows = read_stream(log, name)
        if len(rows) and "t_s" in rows.dtype.names:
            assert rows["t_s"][-1] <= t_end
    # the run logged for a while first: its streams' rows come at the devices', the loop's and
    # the truth's fixed rates (some 0.6 MB/s with the run.mcap), so the 700 kB last about a
    # second of the spin-up; a loaded machine drops rows and fills it later, never sooner
    assert read_stream(log, "loop")["t_s"][-1] > 0.5


def _signal_run(tmp_path, signum: int, group: bool, second: bool):
    log = tmp_path / "log"
    cmd = [sys.executable, "-m", "gyrohost", "run", "--config", str(CONFIG_PATH), "--sim"]
    cmd += ["--schedule", str(schedule_file(tmp_path, L0 - 0.1, 2.0)), "-o", str(log)]
    proc = subprocess.Popen(
        cmd, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True
    )
    send = (lambda: os.killpg(proc.pid, signum)) if group else lambda: proc.send_signal(signum)
    try:
        wait_for(log / "events.csv", "phase,schedule", 60.0)
        send()
        if second:
            wait_for(log / "events.csv", "safe_state,reason", 30.0)
            send()
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    return proc.returncode, out.decode(), err.decode(), log


@pytest.mark.parametrize(
    ("signum", "group", "status", "name"),
    [(signal.SIGTERM, False, 143, "SIGTERM"), (signal.SIGHUP, True, 129, "SIGHUP")],
)
def test_sigterm_and_sighup_end_in_the_safe_state(tmp_path, signum, group, status, name):
    """SIGTERM to the CLI (``kill``); SIGHUP to the whole group (a closed terminal: the rig
    process gets it too and keeps serving). A second one during the safe state is ignored."""
    code, out, err, log = _signal_run(tmp_path, signum, group, second=True)
    assert code == status, err
    assert "Traceback" not in err
    assert f"stopped in the safe state: interrupted ({name})" in err
    safe = assert_log(log)
    assert all(s["ok"] for s in safe["steps"]), safe["steps"]
    assert safe["wheels_stopped"] and safe["servos_holding"]
    assert any(k == "interrupt" and name in m for k, m in events(log))


def test_a_wheel_board_reset_mid_run_is_named_and_its_coasting_wheels_reported(tmp_path):
    """The board down for 1 s (a bootloader): silent first, then booted with its drives off and
    the wheels coasting: the summary names the reset and the speeds measured at exit."""

    def reset(loop, phase, t_s):
        if phase == "schedule" and not hasattr(loop, "injected"):
            loop.injected = True
            loop.rig.inject("wheels", "reset", duration_s=1.0)

    result, folder = run(tmp_path, short_schedule(duration_s=2.0), SHORT, on_tick=reset)
    assert result.exit_status == 1, result.reason
    safe = assert_log(folder)
    steps = {s["step"]: s for s in safe["steps"]}
    assert not steps["stop wheels"]["ok"] and not safe["wheels_stopped"]
    assert "wheel board reset" in safe["wheels"] and "ramped down" not in safe["wheels"]
    assert len(safe["wheel_board_resets"]) == 1 and "rebooted" in safe["wheel_board_resets"][0]
    fastest = safe["wheel_speed_max_rad_s"]
    assert fastest == max(abs(w) for w in safe["wheel_speeds_at_exit_rad_s"])
    truth = read_stream(folder, "truth")
    true_fastest = max(abs(truth[f"omega_{i}_rad_s"][-1]) for i in range(4))
    assert fastest > 30.0 and abs(true_fastest - fastest) < 5.0  # measured, coasting
    assert safe["servos_holding"]


def test_a_silent_servo_is_declared_at_its_first_time_out_while_the_other_follows(tmp_path, capfd):
    """Servo s13 (ID 1) stops answering mid-schedule: the run ends after one reply time-out
    (0.2 s on the simulated rig), naming it; meanwhile s24 keeps receiving its goals."""
    rate_m_s = 0.05
    schedule = Schedule(
        ("s13", "s24"), [0.0, 1.0], [[L0, L0], [L0 - rate_m_s, L0 + rate_m_s]], "both move"
    )

    times = {"silent_s": None}

    def silence(loop, phase, t_s):
        if phase == "schedule" and t_s - loop.t_schedule_s > 0.3 and times["silent_s"] is None:
            loop.rig.inject("servos", "timeout", servo_id=1)
            times["silent_s"] = loop.now()

    result, folder = run(tmp_path, schedule, SHORT, on_tick=silence)
    assert times["silent_s"] is not None, f"ended before the servo fell silent: {result.reason}"
    assert result.exit_status == 1 and "servo 's13' (ID 1)" in result.reason, result.reason
    assert "silent" in result.reason
    e = read_stream(folder, "events")
    t_end = float(e["t_s"][list(e["kind"]).index("end")])
    silent_s = times["silent_s"]
    assert 0.0 < t_end - silent_s < 0.3
    cmd, truth = read_stream(folder, "command"), read_stream(folder, "truth")
    commanded = np.diff(np.interp([silent_s, t_end], cmd["t_s"], cmd["s24_rest_m"]))[0]
    assert commanded > 0.5 * rate_m_s * (t_end - silent_s)  # the loop kept commanding
    followed = np.diff(np.interp([silent_s, t_end], truth["t_s"], truth["s24_rest_m"]))[0]
    # goals held back for the time-out would leave s24 at the goal it had when s13 fell silent
    assert followed > 0.5 * commanded, (followed, commanded)
    s13 = np.diff(np.interp([silent_s, t_end], truth["t_s"], truth["s13_rest_m"]))[0]
    assert abs(s13) < 0.2 * commanded  # the silent servo goes no farther than the goal it had
    for stream in ("servos", "innov_servos"):  # nothing read after it, so nothing stale fused
        assert not any(read_stream(folder, stream)["t_s"] > silent_s), stream
    safe = assert_log(folder)
    assert not safe["servos"]["s13"]["holding"] and "no read-back" in safe["servos"]["s13"]["why"]
    assert safe["servos"]["s24"]["holding"]  # held, not stalled behind s13 in a bulk read
    assert "Traceback" not in capfd.readouterr().err
