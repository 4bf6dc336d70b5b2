"""The estimator's keys refused where they cannot describe a rig: beyond a sensor's full scale
or the rig's size, an IMU frame of repeated or aligned nodes, a table that is not one."""

import pytest

from gyrohost.estimator import EstimatorConfigError
from gyrohost.estimator.config import EstimatorConfig, config_from_dict, read_table
from gyrohost.estimator.imu_model import ImuGeometry
from gyrotensegrity import Model, scene_from_dict


@pytest.mark.parametrize(
    ("keys", "message"),
    [
        (
            {"imu_accel_std_m_s2": 1e300},
            r"'imu_accel_std_m_s2' is 1e\+300, must be in \[0\.0, 156\.",
        ),
        ({"imu_rate_std_rad_s": 40.0}, r"'imu_rate_std_rad_s' is 40\.0, must be in \[0\.0, 34\."),
        ({"accel_psd_m2_s3": 1e5}, r"'accel_psd_m2_s3' is 100000\.0, must be in \[0\.0, 10000"),
        ({"init_position_std_m": 11.0}, r"'init_position_std_m' is 11\.0"),
        ({"imu_frame_nodes": ["n1", "n1", "n1"]}, r"\['n1', 'n1', 'n1'\]: three different nodes"),
        (  # a sample's 330 bits at 9600 baud (20 Hz): 34 ms, past the 30 ms the grid allows
            {"imu_latency_s": 0.0344, "imu_period_s": 0.05},
            r"'imu_latency_s' = 0\.0344 s exceeds 'imu_max_delay_s' = 0\.03 s",
        ),
    ],
)
def test_an_implausible_key_names_itself(keys, message):
    with pytest.raises(EstimatorConfigError, match=message):
        config_from_dict(keys, "ekf.toml")


def test_the_defaults_are_plausible():
    assert config_from_dict({}) == EstimatorConfig()


def test_a_value_that_is_not_a_table_is_refused_naming_the_file(tmp_path):
    path = tmp_path / "ekf.toml"
    path.write_text("estimator = 3\n")
    with pytest.raises(EstimatorConfigError, match=r"ekf\.toml: key 'estimator' must be a table"):
        read_table(path)
    with pytest.raises(EstimatorConfigError, match=r"must be a table, got int 3"):
        config_from_dict(3, "ekf.toml")


def test_an_imu_frame_of_nodes_on_a_line_is_refused():
    line = {
        "scene": {"name": "line", "gravity": [0.0, 0.0, -9.81]},
        "nodes": {"a": [0.0, 0.0, 0.0], "b": [0.2, 0.0, 0.0], "c": [0.4, 0.0, 0.0],
                  "d": [0.2, 0.3, 0.0]},
        "bars": [{"name": "ab", "nodes": ["a", "b"], "mass": 0.1},
                 {"name": "cd", "nodes": ["c", "d"], "mass": 0.1}],
    }  # fmt: skip
    model = Model(scene_from_dict(line))
    with pytest.raises(EstimatorConfigError, match=r"\['a', 'b', 'c'\] lie on a line in scene"):
        ImuGeometry(model, EstimatorConfig(imu_frame_nodes=("a", "b", "c")))
    ImuGeometry(model, EstimatorConfig(imu_frame_nodes=("a", "b", "d")))  # a plane
