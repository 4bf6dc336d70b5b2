"""A run on the simulated rig whose schedule is called ``../../x``, then its log damaged as a
field user will have it (a bad row, a last row cut by a power loss, a missing stream):
``gyrotens replay`` and ``gyrotens plot`` read what they can, warn naming file, row and column,
and write nothing outside their output folder."""

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gyrohost.cli import main
from gyrohost.run.log import read_meta, read_stream

L0 = 0.43105229381822
SCHEDULE = f"""[schedule]
name = "../../x"
t_s = [0.0, 1.0]

[rest_length_m]
s13 = [{L0!r}, 0.40]
"""
GROUPS = ("nodes_m", "velocities_m_s", "wheels_rad_s", "rest_lengths_m", "gyro_bias_rad_s")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """``gyrotens run --sim`` in ``work/`` with the default log folder; the whole tree."""
    root = tmp_path_factory.mktemp("named")
    (root / "schedule.toml").write_text(SCHEDULE)
    (root / "work").mkdir()
    cmd = [sys.executable, "-m", "gyrohost", "run", "--sim", "--schedule", "../schedule.toml"]
    proc = subprocess.run(cmd, cwd=root / "work", capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return root


@pytest.fixture
def log(run_dir, tmp_path):
    """A copy of the run's log, to damage."""
    (source,) = (run_dir / "work" / "out" / "runs").iterdir()
    return Path(shutil.copytree(source, tmp_path / "log"))


def test_a_schedule_name_cannot_leave_the_log_folder(run_dir):
    found = sorted(str(p.relative_to(run_dir)) for p in run_dir.glob("**/") if p != run_dir)
    (folder,) = (run_dir / "work" / "out" / "runs").iterdir()
    assert folder.name.endswith("-_.._x")
    assert found == ["work", "work/out", "work/out/runs", f"work/out/runs/{folder.name}"]
    assert sorted(p.name for p in run_dir.iterdir()) == ["schedule.toml", "work"]


def test_intact_log_replays_without_warnings_and_matches_the_run(log, tmp_path, capsys):
    assert main(["replay", str(log), "-o", str(tmp_path / "r")]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert "final status 0x" in out and "; wrote" in out
    assert "against the run's estimate (" in out and "largest difference: nodes " in out
    summary = read_meta(tmp_path / "r")["summary"]
    compared = summary["compare_live"]
    live, replayed = read_stream(log, "estimate"), read_stream(tmp_path / "r", "estimate")
    # Every row of the run's estimate from the replay's first step on. The replay starts at the
    # run's first row; its IMU grid, fitted to every arrival, may put the first sample up to the
    # IMU's largest delay later than the run's grid, fitted to those so far, did: the run's rows
    # before that (a loaded machine has shown two) have nothing to compare with.
    start_s = replayed["t_s"][0]
    assert 0.0 <= start_s - live["t_s"][0] <= read_meta(log)["estimator"]["imu_max_delay_s"]
    assert summary["warnings"] == [] and compared["rows"] == np.sum(live["t_s"] >= start_s)
    assert set(GROUPS) <= set(compared)
    # The largest node difference, found row by row from the two logs. Not asserted small: on a
    # loaded machine the run's filter (at most 4 samples of a device per tick, ticks up to 0.5 s
    # late) has been seen 1.4 rad off the truth's tilt while the replay followed it.
    q = [c for c in live.dtype.names if c.startswith("q_")]
    worst = 0.0
    for row in live:
        before = replayed[replayed["t_s"] <= row["t_s"]]
        if len(before):
            worst = max(worst, max(abs(before[-1][c] - row[c]) for c in q))
    assert compared["nodes_m"] == worst


def _replayed(log, out) -> dict:
    assert main(["replay", str(log), "-o", str(out)]) == 0
    return read_meta(out)["summary"]


def _damage_row(path: Path, row: int, column: int, value: str) -> None:
    lines = path.read_text().split("\n")
    fields = lines[row - 1].split(",")
    fields[column] = value
    lines[row - 1] = ",".join(fields)
    path.write_text("\n".join(lines))


def test_a_bad_row_is_skipped_with_a_warning_naming_file_row_and_column(log, tmp_path, capsys):
    shutil.copytree(log, log.with_name("intact"))
    _damage_row(log / "imu.csv", 40, 2, "1.2.3")
    assert main(["replay", str(log), "-o", str(tmp_path / "r")]) == 0
    out, err = capsys.readouterr()
    assert err == (
        f"gyrotens replay: warning: {log / 'imu.csv'}: row 40, column 'omega_y_rad_s': "
        "'1.2.3' is not a number; row skipped\n"
    )
    summary = read_meta(tmp_path / "r")["summary"]
    intact = _replayed(log.with_name("intact"), tmp_path / "intact-replay")
    assert len(summary["warnings"]) == 1 and summary["final_status"] == intact["final_status"]
    # one sample less moves the estimate by less than its own 1-sigma, at every row (the
    # largest move is about 1 mm where the D-bar turns fastest; the sigmas there are larger)
    assert _largest_move_in_sigmas(tmp_path / "r", tmp_path / "intact-replay") < 1.0


def _largest_move_in_sigmas(replay: Path, reference: Path) -> float:
    """Largest ``|replay - reference| / std`` of any node coordinate at the reference's rows,
    the replay's estimate interpolated to their times (without the sample its IMU grid is
    rebuilt a little off the reference's, and in a fast turn its row 10 ms before is alone
    more than a sigma away)."""
    a, b = read_stream(replay, "estimate"), read_stream(reference, "estimate")
    rows = (b["t_s"] >= a["t_s"][0]) & (b["t_s"] <= a["t_s"][-1])
    moves = [
        np.abs(np.interp(b["t_s"][rows], a["t_s"], a[c]) - b[c][rows]) / b[f"std_{c}"][rows]
        for c in b.dtype.names
        if c.startswith("q_")
    ]
    return float(np.max(moves))


def test_a_log_cut_by_a_power_loss_replays_to_where_it_ends(log, tmp_path, capsys):
    for name in ("imu", "wheels", "servos", "command", "estimate"):
        path = log / f"{name}.csv"
        data = path.read_bytes()
        path.write_bytes(data[: int(len(data) * 0.7)] + b"\0" * 100)  # cut, NULs after
    assert main(["replay", str(log), "-o", str(tmp_path / "r")]) == 0
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert len(lines) == 5 and all("cut short" in line for line in lines)
    assert f"{log / 'imu.csv'}: row " in err
    assert "final status" in out and "against the run's estimate" in out


def test_a_missing_stream_is_left_out_and_said(log, tmp_path, capsys):
    (log / "wheels.csv").unlink()
    assert main(["replay", str(log), "-o", str(tmp_path / "r")]) == 0
    out, err = capsys.readouterr()
    assert err == (
        f"gyrotens replay: warning: {log}: no stream 'wheels' (wheels.csv or its schema "
        "missing); replayed without it\n"
    )
    (status,) = [line for line in out.splitlines() if line.startswith("final status")]
    assert "WHEELS_TIMEOUT" in status  # the final status, in words


def test_no_imu_is_one_line_and_nothing_written(log, tmp_path, capsys):
    (log / "imu.csv").write_bytes(b"")
    assert main(["replay", str(log), "-o", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[-1] == f"gyrotens replay: error: {log}: no imu samples to replay"
    assert "empty (no header line); replayed without it" in err[0]
    assert not (tmp_path / "r").exists()


def test_plot_of_a_replay_leaves_out_what_it_has_no_data_for(log, tmp_path, capsys):
    replayed = tmp_path / "r"
    assert main(["replay", str(log), "-o", str(replayed)]) == 0
    capsys.readouterr()
    assert main(["plot", str(replayed)]) == 0
    out, err = capsys.readouterr()
    assert sorted(p.name for p in (replayed / "plots").iterdir()) == [
        "attitude.png",
        "innovations.png",
    ]
    assert out.split() == [str(replayed / "plots" / n) for n in ("attitude.png", "innovations.png")]
    assert err.splitlines() == [
        f"gyrotens plot: warning: {name} left out: no rows in {replayed} of {streams}"
        for name, streams in (
            ("fig7-nodes.png", "nodes, truth"),
            ("wheels.png", "wheels, command"),
            ("loop-jitter.png", "loop"),
        )
    ]


def test_plot_of_a_damaged_log_draws_what_it_can(log, tmp_path, capsys):
    (log / "loop.csv").unlink()
    _damage_row(log / "wheels.csv", 5, 1, "")
    assert main(["plot", str(log), "-o", str(tmp_path / "p")]) == 0
    out, err = capsys.readouterr()
    assert len(out.split()) == 6 and "loop-jitter.png" not in out
    assert err.splitlines() == [
        f"gyrotens plot: warning: {log}: no stream 'loop' (loop.csv or its schema missing); "
        "left out",
        f"gyrotens plot: warning: {log / 'wheels.csv'}: row 5, column 'omega_0_rad_s': '' is "
        "not a number; row skipped",
        f"gyrotens plot: warning: loop-jitter.png left out: no rows in {log} of loop",
    ]


def test_plot_with_nothing_to_draw_writes_nothing(tmp_path, capsys):
    from gyrohost.run.log import RunLog

    with RunLog(tmp_path / "log", {}) as run:
        run.stream("loop", ["t_s"])
    assert main(["plot", str(tmp_path / "log")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[-1] == f"gyrotens plot: error: {tmp_path / 'log'}: no stream with rows to plot; " \
        "nothing written"  # fmt: skip
    assert not (tmp_path / "log" / "plots").exists()


def test_many_bad_rows_print_ten_warnings_and_keep_them_all(log, tmp_path, capsys):
    for row in range(20, 32):
        _damage_row(log / "servos.csv", row, 0, "t")
    assert main(["replay", str(log), "-o", str(tmp_path / "r")]) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 11 and all("servos.csv: row " in line for line in err[:10])
    assert err[-1] == (
        f"gyrotens replay: warning: 2 more warnings not shown (12 in all, in "
        f"{tmp_path / 'r'}/meta.json, summary.warnings)"
    )
    assert len(read_meta(tmp_path / "r")["summary"]["warnings"]) == 12


def _insert_rows(path: Path, after: dict) -> None:
    """Insert rows into a stream file: ``after`` maps a row number (1 the header) to the
    lines to put after it, each a function of the file's lines."""
    lines = path.read_text().split("\n")
    out = []
    for number, line in enumerate(lines, 1):
        out.append(line)
        out += after.get(number, lambda _: [])(lines)
    path.write_text("\n".join(out))


def _with_value(line: str, column: int, value: str) -> str:
    fields = line.split(",")
    fields[column] = value
    return ",".join(fields)


def test_non_finite_rows_and_time_running_backwards_are_warned_about_and_never_fused(
    log, tmp_path, capsys
):
    intact = _replayed(shutil.copytree(log, tmp_path / "intact"), tmp_path / "intact-replay")
    capsys.readouterr()
    _insert_rows(log / "imu.csv", {
        40: lambda lines: [_with_value(lines[39], 1, "nan"), _with_value(lines[39], 4, "inf")],
        80: lambda lines: [_with_value(lines[79], 6, "-1e999")],  # inf when read
        300: lambda lines: lines[99:199],  # 100 rows written twice: time runs back 2 s
        350: lambda lines: [lines[349]],  # the same row twice
    })  # fmt: skip
    assert main(["replay", str(log), "-o", str(tmp_path / "r")]) == 0
    out, err = capsys.readouterr()
    imu = log / "imu.csv"
    assert err.splitlines() == [
        f"gyrotens replay: warning: {imu}: 3 of {intact['log_rows']['imu']['rows'] + 104} rows "
        "with a value that is not finite (NaN, inf) (rows 41-42, 83, the first in "
        "'omega_x_rad_s': 'nan'); not fused",
        f"gyrotens replay: warning: {imu}: 100 of {intact['log_rows']['imu']['rows'] + 104} "
        "rows whose time runs backwards (rows 304-403); not fused",
        f"gyrotens replay: warning: {imu}: 1 of {intact['log_rows']['imu']['rows'] + 104} rows "
        "repeating the row before at the same time (row 454); not fused",
    ]
    summary = read_meta(tmp_path / "r")["summary"]
    assert summary["log_rows"]["imu"] == {
        "rows": intact["log_rows"]["imu"]["rows"] + 104,
        "unreadable": 0,
        "non_finite": 3,
        "backwards": 100,
        "repeated": 1,
    }
    assert "  imu: 104 not fused (3 non-finite, 100 backwards, 1 repeated)" in out
    # the rows fused are the intact log's: the same counts, the same final status
    assert summary["sources"] == intact["sources"]
    assert summary["final_status"] == intact["final_status"]


def test_swapped_and_missing_columns_and_a_header_only_stream_are_left_out(log, tmp_path, capsys):
    imu = (log / "imu.csv").read_text().split("\n")
    imu[0] = _with_value(_with_value(imu[0], 1, "omega_y_rad_s"), 2, "omega_x_rad_s")
    (log / "imu.csv").write_text("\n".join(imu))
    wheels = (log / "wheels.csv").read_text().split("\n")
    wheels[0] = wheels[0].replace(",seq", "")
    (log / "wheels.csv").write_text("\n".join(wheels))
    servos = log / "servos.csv"
    servos.write_text(servos.read_text().split("\n")[0] + "\n")
    assert main(["replay", str(log), "-o", str(tmp_path / "r")]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"gyrotens replay: warning: {log / 'imu.csv'}: header differs from meta.json's columns "
        "(columns 'omega_y_rad_s', 'omega_x_rad_s' swapped); replayed without it",
        f"gyrotens replay: warning: {log / 'wheels.csv'}: header differs from meta.json's "
        "columns (missing 'seq'); replayed without it",
        f"gyrotens replay: warning: {servos}: no rows (header only); replayed without it",
        f"gyrotens replay: error: {log}: no imu samples to replay",
    ]
    assert not (tmp_path / "r").exists()


def test_identify_refuses_a_log_with_too_many_bad_rows_naming_them(log, tmp_path, capsys):
    _insert_rows(log / "imu.csv", {300: lambda lines: lines[99:199]})
    out = tmp_path / "i.toml"
    assert main(["identify", str(log), "-o", str(out), "--method", "filter"]) == 2
    err = capsys.readouterr().err
    assert err.splitlines()[-1].startswith(f"gyrotens identify: error: {log / 'imu.csv'}: 100 of ")
    assert "rows cannot be fused (100 backwards: rows 301-400), more than the 1 % " in err
    assert not out.exists()
