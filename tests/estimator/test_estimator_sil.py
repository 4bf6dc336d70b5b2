"""The filter on the rig's own truth model and IMU emulator (in process, simulated clock): a
short software-in-the-loop check; the 20-run Monte Carlo is
``python -m gyrohost.experiments.estimator_sil``."""

import numpy as np

from gyrohost.config import load_rig_config
from gyrohost.experiments.estimator_sil import RIG_MODEL_KEYS, score_rig_model_run
from gyrohost.resources import shipped

CONFIG = shipped("config", "sim-rig")


def test_filter_tracks_the_rig_truth_model():
    result = score_rig_model_run(load_rig_config(CONFIG), seed=3, duration_s=1.2,
                                 overrides=RIG_MODEL_KEYS)  # fmt: skip
    late = result.t_s >= 0.2
    assert np.degrees(result.tilt_rad).max() < 0.2
    assert result.nees_dof == 25
    assert np.mean(result.nees[late]) < 2.0 * result.nees_dof
    for source in ("imu_rate", "imu_angle", "servos"):
        _, nis, dof = result.nis[source]
        assert 0.3 * dof[0] < np.mean(nis) < 2.0 * dof[0], source
