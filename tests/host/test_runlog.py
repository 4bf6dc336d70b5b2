import json
import signal
import subprocess
import sys

import numpy as np
import pytest

from gyrohost.run.errors import LogError
from gyrohost.run.log import RunLog, read_meta, read_stream


def _log_with_imu(folder, rows):
    with RunLog(folder, {"config": {"rate_hz": 100}}) as log:
        s = log.stream("imu", ["t_s", "omega_x_rad_s", "event"], text_columns=["event"])
        for r in rows:
            s.write(*r)
    return folder


def test_round_trip_is_bit_exact(tmp_path):
    rng = np.random.default_rng(1)
    values = rng.normal(size=50) * 1e-7
    rows = [(i * 0.01, v, "ok") for i, v in enumerate(values)]
    data = read_stream(_log_with_imu(tmp_path / "log", rows), "imu")
    assert np.array_equal(data["omega_x_rad_s"], values)
    assert list(data["event"]) == ["ok"] * 50


def test_numpy_reads_a_stream_in_one_line(tmp_path):
    folder = _log_with_imu(tmp_path / "log", [(0.0, 1.5, "a"), (0.01, -2.0, "b")])
    arr = np.genfromtxt(folder / "imu.csv", delimiter=",", names=True, dtype=None, encoding=None)
    assert arr["omega_x_rad_s"].tolist() == [1.5, -2.0]


def test_meta_is_self_describing(tmp_path):
    meta = read_meta(_log_with_imu(tmp_path / "log", []))
    assert meta["streams"]["imu"]["columns"] == ["t_s", "omega_x_rad_s", "event"]
    assert meta["config"] == {"rate_hz": 100}


def test_row_cut_short_by_a_crash_is_dropped(tmp_path):
    folder = _log_with_imu(tmp_path / "log", [(0.0, 1.0, "a"), (0.01, 2.0, "b")])
    with open(folder / "imu.csv", "a") as f:
        f.write("0.02,3.")
    assert read_stream(folder, "imu")["omega_x_rad_s"].tolist() == [1.0, 2.0]


def test_malformed_row_names_file_and_row(tmp_path):
    folder = _log_with_imu(tmp_path / "log", [(0.0, 1.0, "a")])
    with open(folder / "imu.csv", "a") as f:
        f.write("0.02,x,b\n")
    with pytest.raises(LogError, match=r"imu.csv: row 3, column 'omega_x_rad_s': 'x' is not a"):
        read_stream(folder, "imu")


def test_damaged_rows_are_skipped_with_a_warning_naming_file_row_and_column(tmp_path):
    folder = _log_with_imu(tmp_path / "log", [(0.0, 1.0, "a")])
    with open(folder / "imu.csv", "ab") as f:
        f.write(b"0.01,x,b\n")  # not a number
        f.write(b"0.02,2.0\n")  # a field missing
        f.write(b"0.03,3.0,c,d\n")  # one too many
        f.write(b"0.04,4\xff.0,e\n")  # a byte that is not ASCII
        f.write(b"0.05,5.0,f\n")
        f.write(b"0.06,6.0,g\n")
        f.write(b"\0\0\0\0")  # what a power loss leaves at the end of a file
    warnings = []
    s = read_stream(folder, "imu", warn=warnings.append)
    assert s["omega_x_rad_s"].tolist() == [1.0, 5.0, 6.0] and s["event"].tolist() == ["a", "f", "g"]
    path = folder / "imu.csv"
    assert warnings == [
        f"{path}: row 9 cut short (no newline at the end: the run stopped while writing it); "
        "row dropped",
        f"{path}: row 3, column 'omega_x_rad_s': 'x' is not a number; row skipped",
        f"{path}: row 4, column 'event': missing (2 fields, the header has 3); row skipped",
        f"{path}: row 5, after column 'event': 4 fields, the header has 3; row skipped",
        f"{path}: row 6, column 'omega_x_rad_s': bytes that are not ASCII text; row skipped",
    ]


def test_an_empty_stream_file_is_refused(tmp_path):
    folder = _log_with_imu(tmp_path / "log", [])
    (folder / "imu.csv").write_bytes(b"")
    with pytest.raises(LogError, match=r"imu.csv: empty \(no header line\)"):
        read_stream(folder, "imu", warn=print)


def test_wrong_number_of_values_is_refused(tmp_path):
    with RunLog(tmp_path / "log", {}) as log:
        s = log.stream("wheels", ["t_s", "omega_rad_s"])
        with pytest.raises(LogError, match="row has 3 values, columns are 2"):
            s.write(0.0, 1.0, 2.0)


def test_refuses_to_overwrite_a_log(tmp_path):
    _log_with_imu(tmp_path / "log", [])
    with pytest.raises(LogError, match="already holds a log"):
        RunLog(tmp_path / "log", {})


def test_not_a_log_folder(tmp_path):
    with pytest.raises(LogError, match="no meta.json"):
        read_meta(tmp_path)
    (tmp_path / "meta.json").write_text(json.dumps({"format": "other"}))
    with pytest.raises(LogError, match="format is 'other'"):
        read_meta(tmp_path)


def test_rows_survive_sigint(tmp_path):
    """Every row written before Ctrl-C is on disk, without any close()."""
    script = f"""
import time
from gyrohost.run.log import RunLog
log = RunLog({str(tmp_path / "log")!r}, {{}})
s = log.stream("wheels", ["t_s", "omega_rad_s"])
for i in range(100):
    s.write(i * 0.001, float(i))
print("written", flush=True)
time.sleep(30)
"""
    p = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "written"
    p.send_signal(signal.SIGINT)
    p.wait(timeout=10)
    data = read_stream(tmp_path / "log", "wheels")
    assert data["omega_rad_s"].tolist() == [float(i) for i in range(100)]


@pytest.mark.parametrize(
    ("content", "what"),
    [
        (b"\xff\xfe\0{", "not valid JSON"),
        (b'{"format": "gyrotens-log", "str', "not valid JSON"),
        (b"[1, 2]", "not a log's meta.json (no table of streams)"),
    ],
)
def test_a_damaged_meta_json_is_one_line(content, what, tmp_path):
    (tmp_path / "meta.json").write_bytes(content)
    with pytest.raises(LogError) as info:
        read_meta(tmp_path)
    assert str(info.value).startswith(f"{tmp_path / 'meta.json'}: {what}")
    assert "\n" not in str(info.value)


def test_a_screen_keeps_bursts_and_leaves_out_rows_that_are_no_samples(tmp_path):
    """Equal times with other values are a burst (one read's samples share their arrival
    stamp) and kept; a row repeated, one running back in time and one not finite are left out,
    counted and warned about once per kind, by file and row."""
    from gyrohost.run.log_screen import LogScreen

    rows = [(0.0, 1.0, "a"), (0.0, 2.0, "a"), (0.0, 2.0, "a"), (0.01, 3.0, "a"),
            (0.005, 4.0, "a"), (0.02, float("nan"), "a"), (0.02, 5.0, "a")]  # fmt: skip
    folder = _log_with_imu(tmp_path / "log", rows)
    warnings = []
    screen = LogScreen(["imu"])
    data = read_stream(folder, "imu", warnings.append, screen)
    assert data["omega_x_rad_s"].tolist() == [1.0, 2.0, 3.0, 5.0]
    assert screen.counts() == {
        "imu": {"rows": 7, "unreadable": 0, "non_finite": 1, "backwards": 1, "repeated": 1}
    }
    path = folder / "imu.csv"
    assert warnings == [
        f"{path}: 1 of 7 rows with a value that is not finite (NaN, inf) (row 7, the first in "
        "'omega_x_rad_s': 'nan'); not fused",
        f"{path}: 1 of 7 rows whose time runs backwards (row 6); not fused",
        f"{path}: 1 of 7 rows repeating the row before at the same time (row 4); not fused",
    ]
    assert len(read_stream(folder, "imu")) == 7  # unscreened: as written


def test_a_screen_refuses_a_stream_with_nothing_to_fuse(tmp_path):
    from gyrohost.run.log_screen import LogScreen, rows_text

    folder = _log_with_imu(tmp_path / "log", [(0.0, float("inf"), "a")])
    with pytest.raises(LogError, match=r"imu.csv: none of its 1 rows can be fused"):
        read_stream(folder, "imu", None, LogScreen(["imu"]))
    assert rows_text([3, 4, 5, 9]) == "rows 3-5, 9"
    assert rows_text(list(range(1, 40, 2))) == "rows 1, 3, 5, 7, 9, 11, 13, 15 and 12 more"
