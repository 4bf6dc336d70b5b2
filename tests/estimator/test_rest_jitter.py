"""The rest-length jitter a rig's steps put on its strings (``config.sawtooth_psd``), against a
string pulled at a steady speed through a servo and a truth written out sample by sample."""

import math

import numpy as np
import pytest

from gyrohost.config import load_rig_config
from gyrohost.estimator.config import PULL_SPEED_M_S, for_rig, sawtooth_psd
from gyrohost.resources import shipped

DT_S = 1e-6  # the written-out string's resolution, s


def seen_rest_length(t_s, truth_dt_s, period_s, servo_speed_m_s, phase_s):
    """The rest length (m) a truth of step ``truth_dt_s`` holds at the times ``t_s``, of a servo
    given a goal ``PULL_SPEED_M_S * period_s`` further every ``period_s``, which it covers at
    ``servo_speed_m_s`` and holds."""
    v = PULL_SPEED_M_S
    k, into = np.divmod(t_s, period_s)
    servo = k * v * period_s + np.minimum(into * servo_speed_m_s, v * period_s)
    held_at = np.floor((t_s - phase_s) / truth_dt_s) * truth_dt_s + phase_s
    return np.interp(held_at, t_s, servo)


@pytest.mark.parametrize(
    "servo_speed_m_s, low, high",
    [(0.12, 0.97, 1.03), (0.15, 0.97, 1.03), (0.2, 0.97, 1.03), (0.5, 0.8, 1.0), (10.0, 0.75, 1.0)],
)
def test_the_sawtooths_spread_is_the_sum_of_the_truths_hold_and_the_servos_steps(
    servo_speed_m_s, low, high
):
    """Peak to peak ``v h`` (the hold) and ``v T (1 - v/V)`` (the goal steps) add in variance
    over the phases of the truth's step against the goals (one run's phase is arbitrary; its
    own spread differs by up to a fifth): the spread the density is built on. For servos up to
    twice the pull's speed (the rig's: 1.5 times) the sum holds within 3 %; servos that jump to
    their goals step where the truth does, and the sum overstates the spread by up to a fifth."""
    h, T, v = 0.005, 0.010, PULL_SPEED_M_S
    t = np.arange(0.0, 20 * T, DT_S)
    summed = v**2 * (h**2 + (T * (1 - v / servo_speed_m_s)) ** 2) / 12
    spreads = [
        np.var(seen_rest_length(t, h, T, servo_speed_m_s, phase_s) - v * t)
        for phase_s in np.arange(16) / 16 * h
    ]
    assert low <= np.mean(spreads) / summed <= high


def test_the_density_of_each_sawtooth_doubled():
    """``2 (p^2 / 12) P`` per sawtooth of peak to peak ``p`` and period ``P``, the sum doubled;
    goals that come faster than the servo covers them (``V <= v``) add no steps of their own."""
    v = PULL_SPEED_M_S
    hold = 2 * (v * 0.005) ** 2 / 12 * 0.005
    steps = 2 * (v * 0.010 * (1 - v / 0.15)) ** 2 / 12 * 0.010
    assert sawtooth_psd(0.005) == pytest.approx(2 * hold, rel=1e-12)
    assert sawtooth_psd(0.005, 0.010, 0.15) == pytest.approx(2 * (hold + steps), rel=1e-12)
    assert sawtooth_psd(0.005, 0.010, 0.05) == sawtooth_psd(0.005)
    assert sawtooth_psd(0.005, 0.010, math.inf) > sawtooth_psd(0.005, 0.010, 0.15)


def test_the_simulated_rig_takes_its_own_steps():
    """The real-time rig's keys: the truth's step, the run loop's 100 Hz goals and the servos'
    0.15 m/s (7.9e-10 m^2 s); a rig without ``[sim]`` noise keys has none."""
    keys = for_rig(load_rig_config(shipped("config", "sim-rig")))
    assert keys.rest_jitter_psd_m2_s == pytest.approx(sawtooth_psd(0.005, 0.01, 0.15))
    assert keys.rest_jitter_psd_m2_s == pytest.approx(7.87e-10, rel=1e-3)
    assert for_rig(load_rig_config(shipped("config", "lab-rig"))).rest_jitter_psd_m2_s == 0.0
