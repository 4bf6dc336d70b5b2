"""The prism on the simulated rig (shipped ``prism-sim-rig``): the truth holds the scene's
initial state until the estimator starts from it, and the truth's IMU reading is the EKF's
predicted measurement for the same state."""

import numpy as np
import pytest

from gyrohost.config import load_rig_config
from gyrohost.estimator.config import for_rig
from gyrohost.estimator.imu_model import ImuGeometry, euler_zyx
from gyrohost.resources import shipped
from gyrohost.simrig.config import sim_config
from gyrohost.simrig.truth import Truth, truth_scene
from gyrotensegrity.dynamics import evaluate

SPIN_UP_S = 1.2
"""Longer than the run's spin-up and start of the lead-in, when the estimator starts, s."""


@pytest.fixture(scope="module")
def rig():
    config = load_rig_config(shipped("config", "prism-sim-rig"))
    truth = sim_config(config).truth
    return config, Truth(truth_scene(config), truth, config.servos.servo)


def _angle_rad(R_a, R_b):
    return float(np.arccos(np.clip((np.trace(R_a.T @ R_b) - 1.0) / 2.0, -1.0, 1.0)))


def test_the_truth_holds_the_scene_initial_state_through_the_spin_up(rig):
    config, truth = rig
    truth.reset()
    N0, R0 = truth.nodes(), truth.attitude()
    s7 = {servo.id: servo.length_at_zero_m for servo in config.servos.servo}
    spins = [bar.wheel.spin0 for bar in truth_scene(config).bars]
    for k in range(round(SPIN_UP_S / truth.dt_s)):
        ramp = min(1.0, k * truth.dt_s / SPIN_UP_S)
        truth.step(s7, [ramp * w for w in spins])
    # the estimator starts here with 2 mm of position std about the scene's initial state
    assert np.max(np.abs(truth.nodes() - N0)) < 1e-4
    assert _angle_rad(R0, truth.attitude()) < 1e-3
    assert np.linalg.norm(truth.imu_truth(truth.t_s).omega_rad_s) < 1e-3


def test_the_truth_imu_reading_is_the_filter_prediction_for_a_moving_prism(rig):
    config, truth = rig
    truth.reset()
    for _ in range(round(0.3 / truth.dt_s)):
        truth.step({1: 0.318}, [60.0, -40.0, 25.0])  # s7 wound in 2 cm: the prism moves
    reading = truth.imu_truth(truth.t_s)
    ev = evaluate(truth.t_s, truth.stepper.x, truth.u, truth.model)  # imu_latency_s is 0
    geo = ImuGeometry(truth.model, for_rig(config))
    R, omega = geo.frame(ev.N[None], ev.N_dot[None])
    f = geo.specific_force(R, ev.N_ddot[None])[0]
    assert np.linalg.norm(reading.omega_rad_s) > 0.05  # it does turn
    assert np.allclose(R[0], reading.R_wb, atol=1e-12)
    assert np.allclose(omega[0], reading.omega_rad_s, atol=1e-4)  # the truth differences
    assert np.allclose(f, reading.specific_force_m_s2, atol=1e-9)
    assert np.allclose(euler_zyx(R)[0], euler_zyx(reading.R_wb[None])[0], atol=1e-12)
