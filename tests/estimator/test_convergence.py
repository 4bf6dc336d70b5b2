"""The filter on synthetic data converges. Its consistency over seeds (NEES and NIS against the
bounds of their average) is a statistical claim: ``python -m studies estimator_montecarlo``."""

import numpy as np

from gyrohost.estimator import TensegrityEKF, sample_feed
from gyrohost.estimator.consistency import tilt_error


def test_converges_on_synthetic_data(model, config, synthetic):
    truth, data = synthetic
    ekf = TensegrityEKF(model, config)  # starts at the scene's state with zero gyro bias
    L = ekf.layout
    trace = []

    def score(e, stream):
        k = int(round(e.t / 0.01))
        if stream == "imu":
            R, _ = e.attitude()
            bias_err = np.linalg.norm(e.x[L.bias] - truth.x[k, L.bias])
            trace.append((tilt_error(R, truth.R_ws[k]), bias_err))

    sample_feed.run(ekf, data, score)
    tilt, bias = np.array(trace).T
    assert np.linalg.norm(truth.x[0, L.bias]) > 0.005  # a bias worth estimating (rad/s)
    assert bias[-1] < 0.3 * bias[0]
    # angle noise is 0.06 deg per axis
    assert np.degrees(tilt[-50:]).max() < 0.15
    assert np.degrees(np.sqrt(np.mean(tilt[-50:] ** 2))) < 0.06
    assert np.degrees(np.abs(np.arccos(truth.R_ws[-1][2, 2]))) > 3.0  # the plane did tilt
    assert all(m.rejected == 0 for m in ekf.monitors.values())
