"""The pieces the safe state relies on, alone: a log that a full disk refuses, and the
interrupting signals (SIGTERM, SIGHUP) raised, held and ignored like Ctrl-C."""

import os
import signal
import time

import pytest
from test_failures import TinyDisk

from gyrohost.run import log as runlog
from gyrohost.run.errors import LogWriteError
from gyrohost.run.log import RunLog, read_meta, read_stream
from gyrohost.sigint import InterruptsHandled, InterruptsHeld, InterruptsRaised, exit_status


def test_a_refused_write_is_recorded_later_rows_dropped_and_the_reserve_frees_the_summary(
    tmp_path, monkeypatch
):
    folder = tmp_path / "log"
    folder.mkdir()
    disk = TinyDisk(folder, runlog.RESERVE_BYTES + 4000)
    monkeypatch.setattr(runlog, "open", disk.open, raising=False)
    log = RunLog(folder, {"what": "test"})
    a = log.stream("a", ["t_s", "x_m"])
    b = log.stream("b", ["t_s", "kind"], text_columns=["kind"])
    t = 0.0
    while log.failure is None:
        t += 0.01
        a.write(t, 1.0 / 3.0)  # 25 bytes a row: the disk fills within 200 rows
        b.write(t, "tick")
    assert "No space left on device" in log.failure
    rows = a.rows, b.rows
    a.write(t + 1.0, 0.0)  # dropped, not raised
    b.write(t + 1.0, "late")
    assert (a.rows, b.rows) == rows
    with pytest.raises(LogWriteError, match=rf"the log ends at t = {log.last_t_s:.3f} s"):
        log.check()
    assert not (folder / ".reserve").exists()  # given back ...
    log.update_meta(summary={"reason": "disk full"})  # ... so the summary fits
    log.close()
    assert read_meta(folder)["summary"]["reason"] == "disk full"
    last = []
    for name, n in (("a", a.rows), ("b", b.rows)):
        got = read_stream(folder, name)
        assert len(got) == n  # whole rows up to the fault, the one cut short dropped
        last.append(got["t_s"][-1])
    assert max(last) == log.last_t_s and min(last) > t - 0.015


def test_a_log_whose_write_failed_raises_when_closed_as_a_context(tmp_path, monkeypatch):
    folder = tmp_path / "log"
    folder.mkdir()
    disk = TinyDisk(folder, runlog.RESERVE_BYTES + 2000)
    monkeypatch.setattr(runlog, "open", disk.open, raising=False)
    with pytest.raises(LogWriteError, match="a.csv"), RunLog(folder, {}) as log:
        s = log.stream("a", ["t_s"])
        for i in range(1000):
            s.write(float(i))


@pytest.mark.parametrize(("signum", "status"), [(signal.SIGTERM, 143), (signal.SIGHUP, 129)])
def test_sigterm_and_sighup_raise_an_interrupt_held_and_ignored_like_ctrl_c(signum, status):
    before = signal.getsignal(signum)  # SIG_IGN for SIGHUP under nohup
    with pytest.raises(KeyboardInterrupt) as raised, InterruptsRaised():
        os.kill(os.getpid(), signum)
        time.sleep(5.0)  # cut short: the handler raises at once
    assert exit_status(raised.value) == status
    with pytest.raises(KeyboardInterrupt) as raised, InterruptsRaised():
        with InterruptsHeld() as held:
            os.kill(os.getpid(), signum)
            got = held.pending  # held, not raised inside
        assert got is not None and got[0] == signum
    assert exit_status(raised.value) == status
    noted = []
    with InterruptsRaised(), InterruptsHandled(lambda s, f: noted.append(s)):
        os.kill(os.getpid(), signum)
    assert noted == [signum]
    assert signal.getsignal(signum) is before  # every handler restored
