"""The rest-length jitter a rig's servo steps put on its strings (``config.sawtooth_psd``),
against a string pulled at a steady speed through a servo written out sample by sample."""

import math

import numpy as np
import pytest

from gyrohost.config import load_rig_config
from gyrohost.estimator.config import PULL_SPEED_M_S, for_rig, sawtooth_psd
from gyrohost.resources import shipped

DT_S = 1e-6  # the written-out string's resolution, s


def servo_off_ramp(t_s, period_s, servo_speed_m_s):
    """How far (m) a servo given a goal ``PULL_SPEED_M_S * period_s`` further every
    ``period_s``, which it covers at ``servo_speed_m_s`` and holds, is off the steady pull at the
    times ``t_s``."""
    v = PULL_SPEED_M_S
    k, into = np.divmod(t_s, period_s)
    return k * v * period_s + np.minimum(into * servo_speed_m_s, v * period_s) - v * t_s


@pytest.mark.parametrize("servo_speed_m_s", [0.12, 0.15, 0.5, 10.0, 1e6])
def test_the_servos_spread_is_that_of_a_wave_of_its_steps_height(servo_speed_m_s):
    """About the ramp a servo rises by ``p = v T (1 - v/V)`` and falls back once a period: the
    spread ``p^2 / 12`` the density is built on, exactly for any speed."""
    T, v = 0.010, PULL_SPEED_M_S
    t = np.arange(0.0, 20 * T, DT_S)
    p = v * T * (1 - v / servo_speed_m_s)
    assert np.var(servo_off_ramp(t, T, servo_speed_m_s)) == pytest.approx(p**2 / 12, rel=1e-3)


def test_the_density_of_the_steps():
    """``2 (p^2 / 12) T``; goals that come faster than the servo covers them (``V <= v``) add no
    steps; smooth servos (``T = 0``) none."""
    v = PULL_SPEED_M_S
    steps = 2 * (v * 0.010 * (1 - v / 0.15)) ** 2 / 12 * 0.010
    assert sawtooth_psd(0.010, 0.15) == pytest.approx(steps, rel=1e-12)
    assert sawtooth_psd(0.010, 0.05) == 0.0
    assert sawtooth_psd(0.0) == 0.0
    assert sawtooth_psd(0.010, math.inf) > sawtooth_psd(0.010, 0.15)


def test_the_simulated_rig_takes_its_own_steps():
    """The real-time rig's keys: the run loop's 100 Hz goals and the servos' 0.15 m/s
    (1.85e-10 m^2 s); a rig without ``[sim]`` noise keys has none."""
    keys = for_rig(load_rig_config(shipped("config", "sim-rig")))
    assert keys.rest_jitter_psd_m2_s == pytest.approx(sawtooth_psd(0.01, 0.15))
    assert keys.rest_jitter_psd_m2_s == pytest.approx(1.85e-10, rel=1e-2)
    assert for_rig(load_rig_config(shipped("config", "lab-rig"))).rest_jitter_psd_m2_s == 0.0
