"""A resting servo's string sits within a count of its command (the goal's rounding, where the
servo stopped): ``rest_hold_std_m`` keeps that spread as the rest lengths' through the lag,
whatever the filter's steps. Checked on the covariance the filter carries, with no read
fused."""

import math

import numpy as np
import pytest

from gyrohost.config import load_rig_config
from gyrohost.drivers.mx12 import steps_per_metre
from gyrohost.estimator import TensegrityEKF
from gyrohost.estimator.config import EstimatorConfig, servo_hold_std
from gyrohost.resources import shipped
from gyrohost.sil.emulator_keys import emulator_keys
from gyrohost.simrig.config import sim_config

HOLD_M = 6e-6
LAG_S = 0.005  # the simulated rig's: shorter than the filter's 10 ms step


def _ekf(model, **keys):
    config = EstimatorConfig(rest_psd_m2_s=0.0, init_rest_std_m=1e-3, servo_lag_s=LAG_S, **keys)
    ekf = TensegrityEKF(model, config)
    ekf.set_input(model.input_at(0.0)[: model.alpha], 0.0)
    return ekf


def _rest_std(ekf):
    return np.sqrt(np.diag(ekf.P)[ekf.layout.rest])


@pytest.mark.parametrize("method", ["lean", "rk4"])
def test_the_hold_is_the_rest_lengths_spread_at_rest_whatever_the_steps(model, method):
    ekf = _ekf(model, rest_hold_std_m=HOLD_M, process_method=method)
    t = 0.0
    for dt in [0.003, 0.007, 0.01, 0.002, 0.008] * 20:  # the run loop's steps vary
        t += dt
        ekf.advance(t)
        # from the start's 1 mm down to the hold within a few lags, then held there
    np.testing.assert_allclose(_rest_std(ekf), HOLD_M, rtol=1e-6)


def test_the_simulated_rig_s_hold_from_its_servos_count_and_band():
    rig = load_rig_config(shipped("config", "sim-rig"))
    keys = emulator_keys(rig)
    count_m = 1.0 / steps_per_metre(rig.servos.servo[0])  # 2 pi 10 mm / 4096 = 15.3 um
    band = sim_config(rig).servos.hold_band_steps
    assert keys["rest_psd_m2_s"] == 0.0
    assert keys["rest_hold_std_m"] == servo_hold_std(count_m, band)
    rounding_and_band = np.random.default_rng(5).uniform(-0.5, 0.5, (2, 400_000))
    rounding_and_band[1] *= 2 * band
    spread_m = count_m * rounding_and_band.sum(axis=0).std()
    assert keys["rest_hold_std_m"] == pytest.approx(spread_m, rel=5e-3)
    assert math.isclose(count_m, 2 * math.pi * 0.010 / 4096)
