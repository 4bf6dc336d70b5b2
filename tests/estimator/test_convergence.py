"""The filter on synthetic data: convergence, and a reduced Monte Carlo consistency check
(the full one, 20 runs of 3 s: ``python -m gyrohost.sil.montecarlo``)."""

import numpy as np

from gyrohost.estimator import TensegrityEKF, sample_feed
from gyrohost.estimator.consistency import tilt_error
from gyrohost.sil.montecarlo import run_monte_carlo, summarise


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


def test_reduced_monte_carlo_is_consistent(model, config):
    results = run_monte_carlo(model, config, runs=3, duration_s=1.0, first_seed=100)
    figures = summarise(results, "[test] ")
    late = figures["nees_after_burn_in"]
    assert late["lo"] <= late["mean"] <= late["hi"]
    for source in ("imu_rate", "imu_accel", "imu_angle", "wheels", "servos"):
        nis = figures[f"nis_{source}"]
        assert nis["lo"] <= nis["mean"] <= nis["hi"], source
        assert nis["inside"] > 0.8, source
    assert figures["tilt_rms_deg"] < 0.1
