"""At connect the wheel board's ramp and speed low-pass are compared with the estimator's model
of them (``wheel_accel_rad_s2``, ``wheel_filter_s``): a notice names the key that differs."""

from dataclasses import replace

import pytest

from gyrohost.config import load_rig_config
from gyrohost.drivers import wheelproto as wp
from gyrohost.estimator.config import for_rig
from gyrohost.resources import shipped
from gyrohost.run.connect import WHEEL_MODEL_PARAMS, wheel_model_differences

DEFAULTS = {name: wp.PARAM_BY_NAME[name].default for name in WHEEL_MODEL_PARAMS}


@pytest.mark.parametrize("config", ["sim-rig", "lab-rig"])
def test_the_shipped_configurations_match_the_firmware_defaults(config):
    est = for_rig(load_rig_config(shipped("config", config)))
    assert est.wheel_lag_s > 0.0  # the commands are modelled
    assert wheel_model_differences(DEFAULTS, est) == []


def test_a_board_ramp_or_low_pass_the_estimator_does_not_know_is_named():
    est = for_rig(load_rig_config(shipped("config", "sim-rig")))
    (ramp,) = wheel_model_differences({**DEFAULTS, "ACCEL_RAD_S2": 150}, est)
    assert "ACCEL_RAD_S2 is 150" in ramp and "wheel_accel_rad_s2 100: set it to 150" in ramp
    (low_pass,) = wheel_model_differences({**DEFAULTS, "SPEED_FILTER_SHIFT": 4}, est)
    assert "SPEED_FILTER_SHIFT 4 reports speeds 15.5 ms behind" in low_pass
    assert "wheel_filter_s is 7.5 ms: set it to 0.0155" in low_pass
    held = replace(est, wheel_lag_s=0.0)  # commands not modelled: nothing to compare
    assert wheel_model_differences({**DEFAULTS, "ACCEL_RAD_S2": 150}, held) == []
