"""The run's estimator in a child process (``gyrohost.run.estimation``): the same filter run as
in the loop's thread, its faults raised in the loop, its lag bounded."""

import math
import time
from contextlib import contextmanager
from dataclasses import replace

import numpy as np
import pytest

from gyrohost.estimator import streams as cols
from gyrohost.estimator.config import EstimatorConfig
from gyrohost.estimator.ekf import Status
from gyrohost.estimator.errors import EstimatorError
from gyrohost.estimator.sample_feed import events
from gyrohost.resources import shipped
from gyrohost.run.errors import EstimatorProcessError
from gyrohost.run.estimation import EstimatorProcess, _Filter, start_state
from gyrohost.sil.synthetic import sensor_streams, simulate_truth
from gyrotensegrity import Model, load_scene

SCENE = shipped("scene", "dbar-gyro")
SERVO_STRINGS = ["s13", "s24"]
MAX_AGE_S = 0.03
TICK_S = 0.01


class MemoryLog:
    """A run log's ``stream`` interface, rows kept in memory."""

    def __init__(self):
        self.rows: dict[str, list] = {}

    def stream(self, name, columns, text_columns=(), description=""):
        rows = self.rows.setdefault(name, [])
        columns = list(columns)

        class Stream:
            def write(self, *values):
                assert len(values) == len(columns), name
                rows.append([float(v) for v in values])

        return Stream()


@pytest.fixture(scope="module")
def model():
    return Model(load_scene(SCENE))


@pytest.fixture(scope="module")
def config():
    return EstimatorConfig()


@pytest.fixture(scope="module")
def calls(model, config):
    """The loop's calls over 0.3 s of a synthetic run: each sample, command and tick in order."""
    truth = simulate_truth(model, config, 0.3, seed=3, accel_psd_m2_s3=1e-6)
    data = sensor_streams(model, config, truth, seed=3)
    names = [s.name for s in model.scene.strings]
    rest_cols = [cols.rest_column(s) for s in names]
    wheel_cols = cols.wheel_speed_columns(len(model.wheel_bars))
    servo_cols = [cols.servo_length_column(s) for s in names]
    out, next_tick = [], TICK_S
    for t, name, i in events(data):
        while t > next_tick:
            out.append(("tick", next_tick))
            next_tick += TICK_S
        row = data[name][i]
        if name == cols.COMMAND:
            out.append(("set_input", [row[c] for c in rest_cols], t, None))
        elif name == cols.IMU:
            imu = [[row[c] for c in group] for group in (cols.IMU_RATE, cols.IMU_ACCEL)]
            out.append(("fuse_imu", t, *imu, [row[c] for c in cols.IMU_ANGLE]))
        elif name == cols.WHEELS:
            out.append(("fuse_wheels", t, [row[c] for c in wheel_cols]))
        else:
            out.append(("fuse_servos", t, [row[c] for c in servo_cols], [0, 1]))
    return out


def _x0(model):
    wheels = [model.scene.bars[b].wheel.spin0 for b in model.wheel_bars]
    return start_state(model, wheels, {})


@contextmanager
def started(model, config, log=None):
    """A child process started (its model built, the filter at the scene's state at 0 s);
    stopped on the way out, ``stop()``'s outcome then in ``proc.outcome``."""
    proc = EstimatorProcess(model, SCENE, config, SERVO_STRINGS, MAX_AGE_S)
    try:
        while not proc.ready():
            pass
        proc.start(MemoryLog() if log is None else log, _x0(model), 0.0)
        yield proc
    finally:
        proc.outcome = proc.stop()


def _through_process(model, config, calls, paced=True):
    """Feed ``calls`` to a child process: one tick per message, each sent once the child has
    logged the tick before (``paced``, as a loop on a fast enough CPU), or all in one message."""
    log = MemoryLog()
    with started(model, config, log) as proc:
        ticks = 0
        for kind, *args in calls:
            getattr(proc, kind)(*args)
            ticks += kind == "tick"
            if kind == "tick" and paced:
                proc.exchange()
                while len(log.rows.get("estimate", [])) < ticks:
                    proc.exchange()
    ok, detail = proc.outcome
    assert ok, detail
    return proc, log


def test_the_process_gives_the_filter_run_of_the_loop_thread(model, config, calls):
    reference = MemoryLog()
    filt = _Filter(model, config, SERVO_STRINGS, _x0(model), 0.0, reference, MAX_AGE_S)
    last = None
    for kind, *args in calls:
        last = filt.call(kind, args) or last
    proc, log = _through_process(model, config, calls)
    assert set(log.rows) == set(reference.rows)  # estimate, nodes and every innovation stream
    for name, rows in reference.rows.items():
        assert len(rows) > 5, name
        assert np.array_equal(np.array(log.rows[name]), np.array(rows)), name
    assert proc.t == last[1] and np.array_equal(proc.x, last[-1])  # the newest estimate
    assert (
        proc.health["nis"]["imu_rate"]["samples"]
        == filt.innovations.tally.table()["imu_rate"]["samples"]
    )
    assert proc.health["not_fused_behind"] == 0


def test_a_process_far_behind_fuses_the_newest_ticks_only_and_catches_up(model, config, calls):
    """Every call in one message: the waiting ticks' samples are left unfused, and their
    sources do not time out for it (time-outs shorter than the stretch left out)."""
    short = replace(config, imu_timeout_s=0.05, wheels_timeout_s=0.05, servos_timeout_s=0.1)
    proc, log = _through_process(model, short, calls, paced=False)
    assert proc.status == Status(0)
    n_ticks = sum(1 for c in calls if c[0] == "tick")
    assert proc.health["not_fused_behind"] > 0
    assert len(log.rows["estimate"]) < n_ticks  # the waiting ticks' estimates left out
    assert proc.t == pytest.approx(n_ticks * TICK_S, abs=MAX_AGE_S + 1e-9)  # caught up


def test_a_filter_fault_is_raised_in_the_loop_and_the_process_still_stops(model, config, calls):
    with started(model, config) as proc:
        proc.set_input([math.nan, 0.4], 0.0)
        proc.tick(0.05)  # predicted to the tick: the strings' forces are NaN
        deadline = time.monotonic() + 30.0
        with pytest.raises(EstimatorError, match="non-finite") as raised:
            while time.monotonic() < deadline:
                proc.exchange()
        assert raised.value.member == "rest0_m" and raised.value.t_s > 0.0
        proc.exchange()  # raised once
    ok, detail = proc.outcome
    assert ok and proc.health is not None, detail


def test_an_estimate_lagging_the_loop_too_far_ends_the_run(model, config):
    with started(model, config) as proc:
        with pytest.raises(EstimatorProcessError, match=r"1\.500 s behind the loop"):
            proc.exchange(1.5, max_lag_s=1.0)


def test_a_scene_the_child_cannot_build_is_named(model, config, tmp_path):
    bad = tmp_path / "missing.toml"
    proc = EstimatorProcess(model, bad, config, SERVO_STRINGS, MAX_AGE_S)
    try:
        with pytest.raises(EstimatorProcessError, match="missing.toml"):
            while not proc.ready():
                pass
    finally:
        ok, detail = proc.stop()
    assert ok and detail == "never started"


def test_a_child_killed_mid_run_is_an_error_naming_its_exit(model, config):
    with started(model, config) as proc:
        proc._proc.kill()
        proc._proc.join(5.0)
        with pytest.raises(EstimatorProcessError, match="exit code -9"):
            for _ in range(100):
                proc.tick(0.01)
                proc.exchange()
    ok, detail = proc.outcome
    assert not ok and "without its summary" in detail
