"""Sweeps run the same on the serial path and on Dask (bitwise for a fixed-step integrator);
failed cases are recorded while the others go on; finished cases are kept and not rerun."""

import math
import subprocess
import sys
import time

import numpy as np
import pytest

from gyrohost import parallel
from gyrohost.cli import main
from gyrohost.parallel import Executor, ExecutorError, Failure
from gyrohost.sweep import load_spec, read_table, run_sweep

SPEC = """
[sweep]
name = "tiny"
scene = "dbar-gyro"
record = ["final_tilt_deg", "peak_node_z_m", "momentum_drift", "wall_s", "N:maxabs", "energy"]

[[axes]]
name = "spin_rad_s"
key = "bars.*.wheel.spin"
op = "magnitude"
values = [20.0, 60.0]

[[axes]]
name = "closure_s"
key = "strings.*.rest_length.t"
op = "stretch"
values = [0.2, -0.5]          # a negative closure time: the case's scene is invalid

[integrator]
integrator = "rk4"
dt = 2e-3
duration = 0.1
sample_dt = 0.01

[pareto]
cost = "spin_rad_s"
goal = "final_tilt_deg"
target = -1.0
"""


def sqrt_or_fail(x):
    if x < 0:
        raise ValueError(f"negative: {x}")
    return math.sqrt(x)


@pytest.fixture(scope="module")
def cluster():
    """A LocalCluster of two single-threaded worker processes, shared by this module's tests."""
    with Executor(workers=2) as executor:
        yield executor


@pytest.fixture
def spec(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(SPEC)
    return load_spec(path)


@pytest.fixture
def one_axis(tmp_path):
    """The tiny sweep over closure time alone: no figure to draw (they need two axes, a pareto)."""
    path = tmp_path / "one-axis.toml"
    text = (
        SPEC[: SPEC.index("[[axes]]")] + SPEC[SPEC.index("[[axes]]", SPEC.index("[[axes]]") + 1) :]
    )
    path.write_text(text[: text.index("[pareto]")])
    return load_spec(path)


def numbers(rows):
    """The rows without what may differ between runs of the same case: its wall time, and
    where a failure was raised (this process or a worker)."""
    return [{k: v for k, v in r.items() if k not in ("wall_s", "traceback")} for r in rows]


def test_serial_and_dask_give_bitwise_the_same_table(spec, tmp_path, cluster):
    serial = run_sweep(spec, tmp_path / "serial", Executor(serial=True))
    dask = run_sweep(spec, tmp_path / "dask", cluster)
    assert (serial.ran, serial.failed) == (4, 2)
    assert numbers(serial.rows) == numbers(dask.rows)  # == on floats: bitwise
    table = read_table(tmp_path / "dask" / "results.parquet")
    assert numbers(table) == numbers(dask.rows)
    ok = [r for r in table if r["error"] is None]
    assert len(ok) == 2 and all(r["final_tilt_deg"] < 0.0 for r in ok)
    assert all(len(r["N:maxabs"]) == 3 * 8 for r in ok)  # 3 x n scene nodes, flattened
    assert ok[1]["final_tilt_deg"] < ok[0]["final_tilt_deg"]  # more spin, more turn
    assert {p.name for p in dask.files} == {"results.parquet", "heatmap.png", "pareto.png"}


def test_a_failed_case_is_recorded_and_the_others_go_on(one_axis, tmp_path):
    result = run_sweep(one_axis, tmp_path, Executor(serial=True))
    assert [r["error"] is None for r in result.rows] == [True, False]
    failed = result.rows[1]
    assert failed["error"].startswith("SceneError: tiny case 1: strings[0].rest_length.t")
    assert failed["final_tilt_deg"] is None and "Traceback" in failed["traceback"]
    assert result.files == [tmp_path / "results.parquet"]


def test_finished_cases_are_kept_and_not_run_again(one_axis, tmp_path):
    first = run_sweep(one_axis, tmp_path, Executor(serial=True))
    again = run_sweep(one_axis, tmp_path, Executor(serial=True))
    assert (again.ran, again.kept) == (1, 1)  # only the failed case is tried again
    assert again.rows[0] == first.rows[0]  # wall time too: read back, not rerun
    one_axis.integrator["dt"] = 1e-3  # a changed setting is another case
    assert run_sweep(one_axis, tmp_path, Executor(serial=True)).ran == 2


def test_executor_keeps_order_and_failures_on_dask(cluster):
    done = []
    items = [4.0, -1.0, 9.0]
    out = cluster.map(sqrt_or_fail, items, keep_going=True, on_done=lambda k, r: done.append(k))
    assert out[0] == 2.0 and out[2] == 3.0
    assert isinstance(out[1], Failure) and out[1].error == "ValueError: negative: -1.0"
    assert sorted(done) == [0, 1, 2]
    with pytest.raises(ValueError, match="negative"):
        cluster.map(sqrt_or_fail, [1.0, -2.0])


def test_a_case_dask_lost_ends_the_map_with_an_error_naming_it(cluster, monkeypatch):
    """Workers that sit idle while a case is pending mean Dask lost it: the map ends with an
    error naming the case instead of waiting forever (a running case, here taken for an idle
    worker's, stands for the lost one)."""
    monkeypatch.setattr(parallel, "STALL_CHECK_S", 0.1)
    monkeypatch.setattr(parallel, "STALL_S", 0.3)
    monkeypatch.setattr(Executor, "_workers_idle", lambda self: True)
    with pytest.raises(ExecutorError, match=r"Dask lost 1 case\(s\) \(items \[1\]\)"):
        cluster.map(time.sleep, [0.0, 2.0])
    time.sleep(2.0)  # the case runs to its end on its worker


def test_a_case_that_runs_longer_than_the_stall_bound_is_waited_for(cluster, monkeypatch):
    """The workers' own account: one that runs a case is not idle, however long it takes."""
    monkeypatch.setattr(parallel, "STALL_CHECK_S", 0.1)
    monkeypatch.setattr(parallel, "STALL_S", 0.3)
    assert cluster.map(time.sleep, [1.0]) == [None]


def test_serial_executor_raises_the_first_error_unless_keep_going():
    serial = Executor(serial=True)
    with pytest.raises(ValueError, match="negative: -2.0"):
        serial.map(sqrt_or_fail, [1.0, -2.0, -3.0])
    assert (
        serial.map(sqrt_or_fail, [-3.0], keep_going=True)[0].error == "ValueError: negative: -3.0"
    )


@pytest.mark.parametrize(
    ("address", "message"),
    [("tcp://127.0.0.1:9", "tcp://127.0.0.1:9"), ("not an address", "missing port number")],
)
def test_an_unreachable_or_malformed_scheduler_is_an_executor_error(address, message):
    with (
        pytest.raises(ExecutorError, match=message),
        Executor(scheduler=address, timeout_s=1.0),
    ):
        pass


def test_cli_sweep_runs_serially_and_a_bad_spec_exits_2(spec, tmp_path, capsys):
    assert main(["sweep", str(spec.path), "-o", str(tmp_path / "out"), "--serial"]) == 1
    out = capsys.readouterr().out
    assert "4 cases: 4 run, 0 kept" in out and "2 failed" in out
    assert "closest to target: spin_rad_s 60" in out
    bad = tmp_path / "bad.toml"
    bad.write_text(SPEC.replace('op = "stretch"', 'op = "squash"'))
    assert main(["sweep", str(bad), "-o", str(tmp_path / "bad")]) == 2
    assert "bad.toml: axes[1].op: 'squash'" in capsys.readouterr().err


def test_cli_sweep_states_its_cases_and_the_first_ones_time_before_the_rest(spec, tmp_path, capsys):
    assert main(["sweep", str(spec.path), "-o", str(tmp_path / "out"), "--serial"]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("tiny: dbar-gyro.toml, 2 axes, 4 cases, serial")
    assert out[1].startswith("4 cases to run; the first took ") and "1 at a time" in out[1]
    assert main(["sweep", str(spec.path), "-o", str(tmp_path / "b"), "--max-cases", "3"]) == 2
    err = capsys.readouterr().err
    assert "4 cases (spin_rad_s 2 x closure_s 2), more than the 3 allowed" in err
    assert not (tmp_path / "b").exists()


REFUSE_IN_2_GB = """
import resource, sys, time
resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))
from gyrohost.cli import main
start = time.perf_counter()
status = main(["sweep", sys.argv[1], "-o", sys.argv[2], "--serial"])
print(f"refused in {time.perf_counter() - start:.3f} s", file=sys.stderr)
sys.exit(status)
"""


def test_a_billion_case_sweep_is_refused_at_once_in_bounded_memory(tmp_path):
    """A ``num`` typed a million times too large: counted, not made (its values alone would
    take 8 GB), and refused under a 2 GB address-space limit without running a case."""
    path = tmp_path / "typo.toml"
    typo = "range = { start = 20.0, stop = 60.0, num = 500000000 }"
    path.write_text(SPEC.replace("values = [20.0, 60.0]", typo))
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-c", REFUSE_IN_2_GB, str(path), str(out)],
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert "1000000000 cases (spin_rad_s 500000000 x closure_s 2), more than the 10000 " in (
        done.stderr
    )
    assert "refused in " in done.stderr and not out.exists()


def test_monte_carlo_runs_the_same_on_dask(cluster):
    from gyrohost.estimator.config import EstimatorConfig
    from gyrohost.resources import shipped
    from gyrohost.sil.montecarlo import run_monte_carlo
    from gyrotensegrity import Model, load_scene

    model = Model(load_scene(shipped("scene", "dbar-gyro")))
    args = (model, EstimatorConfig(), 2, 0.05)
    serial, dask = run_monte_carlo(*args), run_monte_carlo(*args, executor=cluster)
    for a, b in zip(serial, dask, strict=True):
        for name in ("t_s", "nees", "tilt_rad", "position_m"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert a.nis.keys() == b.nis.keys()
        assert all(np.array_equal(a.nis[s][1], b.nis[s][1]) for s in a.nis)
    assert not np.array_equal(serial[0].nees, serial[1].nees)  # two seeds, two runs
