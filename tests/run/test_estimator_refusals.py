"""A bad estimator file stops a run before anything is opened or moved: exit 2, one line naming
the file and the key, no log folder (so no spin-up)."""

import pytest

from gyrohost.cli import main


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('[estimator]\nimu_frame_nodes = ["n1", "n1", "n1"]\n', "three different nodes"),
        ("[estimator]\nimu_accel_std_m_s2 = 1e300\n", "'imu_accel_std_m_s2' is 1e+300"),
        ("estimator = 3\n", "key 'estimator' must be a table, got int 3"),
    ],
)
def test_a_bad_estimator_file_is_refused_before_the_rig_starts(tmp_path, capsys, text, message):
    path = tmp_path / "ekf.toml"
    path.write_text(text)
    log = tmp_path / "log"
    assert main(["run", "--sim", "--estimator", str(path), "-o", str(log)]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and message in err and "Traceback" not in err
    assert not log.exists()
