"""The run loop against the simulated rig (its own process, real time): a complete run logs every
stream; Ctrl-C, device faults and limit breaches end in the safe state with a readable log."""

import math
import os
import signal
import threading
import time
from contextlib import contextmanager
from dataclasses import replace

import numpy as np
import pytest

from gyrohost.commands.run import report
from gyrohost.config import load_rig_config
from gyrohost.control.schedule import Schedule
from gyrohost.gcfreeze import heap_frozen
from gyrohost.resources import shipped
from gyrohost.run import RunSettings, ScheduleRefused, run_simulated, sequence
from gyrohost.run.log import read_meta, read_stream

CONFIG = load_rig_config(shipped("config", "sim-rig"))
L0 = 0.43105229381822  # both D-bar strings at rest, m
SPIN = 74.87462492  # rad/s
SHORT = RunSettings(lead_in_s=0.2, settle_s=0.2)
INPUT_STREAMS = ("imu", "wheels", "servos", "command", "servo_goals")
OUTPUT_STREAMS = ("estimate", "nodes", "innov_imu_rate", "innov_wheels", "innov_servos")
RUN_STREAMS = ("truth", "loop", "events")


def short_schedule(end_m: float = L0 - 0.05, duration_s: float = 1.0) -> Schedule:
    """s13 shortened linearly (0.05 m/s by default), s24 held."""
    t = np.array([0.0, duration_s])
    return Schedule(("s13", "s24"), t, [[L0, L0], [end_m, L0]], "short")


def run(tmp_path, schedule=None, settings=SHORT, on_tick=None):
    folder = tmp_path / "log"
    result = run_simulated(
        CONFIG, schedule or short_schedule(), folder, settings=settings, on_tick=on_tick
    )
    return result, folder


def events(folder) -> list[tuple[str, str]]:
    e = read_stream(folder, "events")
    return list(zip(e["kind"], e["message"], strict=True))


def assert_safe_state(folder, result):
    """Wheels commanded to zero and slowing (truth), servos holding, the outcome logged."""
    safe = result.summary["safe_state"]
    assert safe["wheels_stopped"] and safe["servos_holding"], safe
    cmd = read_stream(folder, "command")
    assert [cmd[f"omega_cmd_{i}_rad_s"][-1] for i in range(4)] == [0.0] * 4
    truth = read_stream(folder, "truth")
    last = max(abs(truth[f"omega_{i}_rad_s"][-1]) for i in range(4))
    peak = max(np.max(np.abs(truth[f"omega_{i}_rad_s"])) for i in range(4))
    assert peak > 0.9 * SPIN and last < 0.3 * SPIN  # spun up, ramped down (the rest coasts)
    kinds = [k for k, _ in events(folder)]
    assert kinds.count("safe_state") == 2  # the reason, then what was reached


def test_a_run_completes_and_logs_every_stream(tmp_path, monkeypatch, capsys):
    threads_at_freeze = []

    @contextmanager
    def recorded_freeze():
        threads_at_freeze.append({t.name for t in threading.enumerate()})
        with heap_frozen():
            yield

    monkeypatch.setattr(sequence, "heap_frozen", recorded_freeze)
    before = {t.name for t in threading.enumerate()}
    result, folder = run(tmp_path)
    assert result.completed and result.exit_status == 0, result.reason
    # the collection before the freeze holds the interpreter: no device thread may be waiting
    # on it (a wheel-board heartbeat held for HEARTBEAT_MS latches the board's fail-safe)
    assert threads_at_freeze == [before]
    silence = result.summary["wheel_board_silence_s"]
    assert 0.0 < silence["max"] < silence["limit"] == 0.5
    capsys.readouterr()
    assert report(result) == 0 and "nothing for" not in capsys.readouterr().err
    silence["max"] = 0.3  # what gyrotens run says of a host that paused that long
    report(result)
    assert "nothing for 300 ms; at 500 ms its fail-safe stops the wheels" in capsys.readouterr().err
    assert set(result.summary["rig_real_time"]) == {"kept", "late_share", "max_lag_s", "slipped_s"}
    result.summary["rig_real_time"] = {  # a CPU too loaded for the rig
        "kept": False, "late_share": 0.6, "max_lag_s": 0.25, "slipped_s": 0.2,
    }  # fmt: skip
    report(result)
    assert "truth did not keep real time (60 % of its steps late" in capsys.readouterr().err
    meta = read_meta(folder)
    for name in INPUT_STREAMS + OUTPUT_STREAMS + RUN_STREAMS:
        assert name in meta["streams"], name
        # one line with numpy, as docs/run.md promises
        rows = np.genfromtxt(folder / f"{name}.csv", delimiter=",", names=True, dtype=None)
        assert rows.size > 3, name
    phases = [m for k, m in events(folder) if k == "phase"]
    assert phases == ["connect", "hold", "spinup", "lead_in", "schedule", "settle"]
    cmd = read_stream(folder, "command")
    assert cmd["s13_rest_m"].min() == pytest.approx(L0 - 0.05, abs=1e-9)
    # each goal the servos were sent is a tick's, stamped when it went out: after that tick
    goals = read_stream(folder, "servo_goals")
    tick = np.searchsorted(cmd["t_s"], goals["t_s"], "right") - 1
    sent = np.flatnonzero(tick >= 0)
    assert len(sent) > 0.5 * len(goals)
    for i in sent:  # a goal made at its tick or one before (only the newest goes out)
        assert goals["s13_rest_m"][i] in cmd["s13_rest_m"][: tick[i] + 1]
    truth = read_stream(folder, "truth")
    assert truth["s13_rest_m"][-1] == pytest.approx(L0 - 0.05, abs=2e-3)  # servo followed
    assert_safe_state(folder, result)
    loop = result.summary["loop"]
    # orders that hold for any periods (one long period can lift the mean above the p99)
    assert loop["ticks"] > 50 and loop["period_max_s"] >= loop["period_p99_s"] > 0  # no timing
    assert loop["period_max_s"] >= loop["period_mean_s"] > 0
    ticks = read_stream(folder, "loop")
    assert len(ticks) == loop["ticks"]  # asserts: the CPU is shared
    fed = np.isin(ticks["phase"], ["schedule", "settle"])
    lag_s = ticks["estimate_lag_s"]
    assert np.all(np.isfinite(lag_s[fed])) and np.all(np.isnan(lag_s[ticks["phase"] == "hold"]))
    lags = result.summary["estimator"]["lag_s"]  # the estimator's own process keeps up
    assert lags["median"] == pytest.approx(np.median(lag_s[np.isfinite(lag_s)]), abs=1e-9)
    assert 0.0 <= lags["median"] <= lags["p99"] <= lags["max"] < 1.0
    est = read_stream(folder, "estimate")
    assert np.all(np.isfinite(est["tilt_rad"]))
    assert (
        abs(result.summary["tilt_end_estimate_rad"] - result.summary["tilt_end_truth_rad"]) < 0.05
    )


def test_ctrl_c_mid_schedule_ends_in_the_safe_state(tmp_path):
    def interrupt(loop, phase, t_s):
        if phase == "schedule" and t_s - loop.t_schedule_s > 0.3:
            raise KeyboardInterrupt

    result, folder = run(tmp_path, on_tick=interrupt)
    assert result.exit_status == 130 and "Ctrl-C" in result.reason
    assert_safe_state(folder, result)
    assert read_meta(folder)["summary"]["reason"] == result.reason
    for name in read_meta(folder)["streams"]:
        read_stream(folder, name)  # every stream reads back whole


@pytest.mark.parametrize(
    ("fault", "expected"),
    [
        (("wheels", "reset"), "wheels: board rebooted"),
        (("servos", "overload"), "overload"),
        (("imu", "silence"), "imu: no sample for 0.5 s"),
    ],
)
def test_an_injected_device_fault_ends_in_the_safe_state_and_is_named(tmp_path, fault, expected):
    def inject(loop, phase, t_s):
        if phase == "schedule" and not hasattr(loop, "injected"):
            loop.injected = True
            kwargs = {"servo_id": 1} if fault[0] == "servos" else {}
            kwargs = {"duration_s": 2.0} if fault[0] == "imu" else kwargs
            loop.rig.inject(*fault, **kwargs)

    result, folder = run(tmp_path, on_tick=inject)
    assert result.exit_status == 1 and expected in result.reason, result.reason
    assert any(k == "end" and expected in m for k, m in events(folder))
    safe = result.summary["safe_state"]
    assert safe["servos_holding"]
    if fault[0] != "wheels":  # a rebooted board lets its wheels coast: nothing to ramp
        assert_safe_state(folder, result)
    if fault[0] == "servos":
        assert "overload" in " ".join(safe["servos"]["s13"]["faults"]).lower()


def break_the_estimator(loop, phase, t_s):
    """A non-finite rest length into the estimator once the schedule plays: its next
    prediction fails (a NaN the filter refuses to carry on with)."""
    if phase == "schedule" and not hasattr(loop, "broken"):
        loop.broken = True
        loop.estimator.set_input([math.nan, L0], t_s)


def test_an_estimator_failure_ends_a_run_that_needs_the_estimate(tmp_path):
    result, folder = run(tmp_path, on_tick=break_the_estimator)
    assert result.exit_status == 1 and "non-finite" in result.reason, result.reason
    assert_safe_state(folder, result)


def test_an_identification_run_records_on_when_its_estimator_fails(tmp_path):
    """Nothing acts on an identification run's estimate (no tilt limit, no maneuver): the
    failure is told and the recording completes with every input stream to its end."""
    schedule = replace(short_schedule(duration_s=1.0), purpose="identification")
    result, folder = run(tmp_path, schedule, on_tick=break_the_estimator)
    assert result.exit_status == 0, result.reason
    told = [m for k, m in events(folder) if k == "notice" and "estimator" in m]
    assert told and "non-finite" in told[0] and "goes on without it" in told[0]
    end = read_stream(folder, "imu")["t_s"][-1]
    assert read_stream(folder, "estimate")["t_s"][-1] < end - 0.5  # the estimate stopped
    assert result.summary["estimator"]["required"] is False
    with_limit = replace(SHORT, max_tilt_rad=1.0)  # a limit on the estimate: it is needed
    result, folder = run(tmp_path / "limited", schedule, with_limit, break_the_estimator)
    assert result.exit_status == 1 and "non-finite" in result.reason, result.reason


def test_a_limit_breach_during_the_run_ends_in_the_safe_state(tmp_path):
    schedule = short_schedule(L0 - 0.1, 1.0)  # tilts the spinning D-bar by several degrees
    result, folder = run(tmp_path, schedule, replace(SHORT, max_tilt_rad=math.radians(1.0)))
    assert result.exit_status == 1 and "LimitBreach: estimated tilt" in result.reason
    assert_safe_state(folder, result)


def test_a_schedule_beyond_the_servo_limits_is_refused_before_anything_moves(tmp_path):
    too_short = short_schedule(0.05, 5.0)  # below s13's min_length_m = 0.12
    with pytest.raises(ScheduleRefused, match=r"s13: rest length 0\.05\.\.0\.4311 m outside"):
        run(tmp_path, too_short)
    too_fast = short_schedule(L0 - 0.1, 0.2)  # 0.5 m/s against max_speed_m_s = 0.15
    with pytest.raises(ScheduleRefused, match=r"s13: speed 0\.5 m/s exceeds 0\.15 m/s"):
        run(tmp_path, too_fast)
    unknown = Schedule(("s99",), [0.0, 1.0], [[L0], [L0]], "unknown")
    with pytest.raises(ScheduleRefused, match="s99: no servo winds this string"):
        run(tmp_path, unknown)
    assert not (tmp_path / "log").exists()  # no log: nothing was opened


def test_the_safe_state_goes_on_whatever_the_truth_probe_raises(tmp_path):
    def broken_truth():
        raise EOFError("a probe that fails the way a desynchronised pipe did")

    def interrupt(loop, phase, t_s):
        if phase == "schedule" and t_s - loop.t_schedule_s > 0.3:
            loop.rig.truth = broken_truth  # the safe state's ticks probe the truth first
            raise KeyboardInterrupt

    result, folder = run(tmp_path, on_tick=interrupt)
    assert result.exit_status == 130, result.reason
    safe = result.summary["safe_state"]
    assert safe["wheels_stopped"] and safe["servos_holding"], safe
    assert any(k == "fault" and m.startswith("truth probe: EOFError") for k, m in events(folder))
    assert read_stream(folder, "command")["omega_cmd_0_rad_s"][-1] == 0.0


def test_a_rig_process_whose_child_is_gone_raises_rig_process_errors():
    from gyrohost.simrig.errors import RigProcessError
    from gyrohost.simrig.process import RigProcess

    with RigProcess(CONFIG) as rig:
        rig._proc.kill()
        rig._proc.join(5.0)
        with pytest.raises(RigProcessError, match="the pipe to the rig ended: EOFError"):
            for _ in range(100):  # the samples sent before the end come first
                rig.truth()
                time.sleep(0.01)
        with pytest.raises(RigProcessError, match="simulated rig"):
            rig.stats()


class _Interrupted(Exception):
    pass


_ARMED = [False]
"""True while ``rig.truth()`` runs: an interrupt elsewhere in the test loop is dropped."""


def _interrupt(signum, frame):
    if _ARMED[0]:
        _ARMED[0] = False  # one raise per call, so none lands in the except clause
        raise _Interrupted


def test_ctrl_c_while_the_truth_is_received_never_breaks_the_pipe():
    """An interrupt inside ``recv`` would leave half a message in the pipe and the next read
    would fail (``EOFError: Ran out of input``) although the rig is alive."""
    from gyrohost.simrig.process import RigProcess

    previous = signal.signal(signal.SIGINT, _interrupt)
    stop = threading.Event()

    def kick():
        while not stop.wait(0.0007):
            os.kill(os.getpid(), signal.SIGINT)

    samples = interrupts = 0
    try:
        with RigProcess(CONFIG, period_s=0.001) as rig:
            kicker = threading.Thread(target=kick)
            kicker.start()
            end = time.monotonic() + 3.0
            try:
                while time.monotonic() < end:
                    try:
                        _ARMED[0] = True
                        samples += len(rig.truth())
                        _ARMED[0] = False
                    except _Interrupted:
                        interrupts += 1
            finally:
                stop.set()
                kicker.join()
            samples += len(rig.truth())  # still whole after thousands of interrupts
    finally:
        signal.signal(signal.SIGINT, previous)
    # every 5 ms step of the truth comes (600 in 3 s): half of them tells a whole pipe
    assert interrupts > 100 and samples > 300, (interrupts, samples)


def test_lost_wheel_frames_are_counted_in_the_summary_and_told(tmp_path, capsys):
    """Bytes of the wheel board's telemetry corrupted mid-run: the frames it drops (CRC
    errors) and the gaps they leave in the sequence numbers are in the summary's ``links`` and
    in a warning line; the estimator's samples per source in the summary and a line."""

    def corrupt(loop, phase, t_s):
        if phase == "schedule" and not hasattr(loop, "corrupted"):
            loop.corrupted = True
            loop.rig.inject("wheels", "corrupt", count=3)  # three bytes: at most three frames

    result, folder = run(tmp_path, on_tick=corrupt)
    wheels = result.summary["links"]["wheels"]
    assert 1 <= wheels["sequence_gaps"] <= 3, (wheels, result.reason)
    assert wheels["sequence_gaps"] <= wheels["frames_lost"]
    assert sum(wheels["frames_dropped"].values()) >= 1, wheels
    seq = read_stream(folder, "wheels")["seq"].astype(int)
    assert int(np.sum(np.diff(seq) % 2**16 != 1)) == wheels["sequence_gaps"]
    assert result.summary["links"]["imu"] == {
        "bad_checksums": 0, "unknown_types": 0, "frames_dropped": 0}  # fmt: skip
    sources = result.summary["estimator"]["sources"]
    assert set(sources) == {"imu_rate", "imu_accel", "imu_angle", "wheels", "servos"}
    assert all(c["accepted"] > 0 for c in sources.values()), sources
    report(result)
    out, err = capsys.readouterr()
    assert "gyrotens run: warning: wheel board link: " in err
    assert f"{wheels['sequence_gaps']} sequence gaps ({wheels['frames_lost']} frames lost)" in err
    assert "estimator samples: imu_rate " in out and " fused, " in out
