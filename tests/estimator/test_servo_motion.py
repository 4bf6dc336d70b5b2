"""The servos' motion (a lag at most at the speed limit) in the filter and in identification,
against the same motion stepped finely (:func:`gyrohost.drivers.mx12.lag_error_after` over 1
us): one prediction step ends where the servo does, a read is taken back through the goals
in effect, and the rendered lengths follow the servo exactly."""

from types import SimpleNamespace

import numpy as np
import pytest

from gyrohost.drivers.mx12 import lag_error_after
from gyrohost.estimator.servo_motion import lag_input, lagged, rest_before, taken_back

LAG_S, SPEED_M_S = 0.0133, 0.15


def fine(start_m, goals, t_end_s, step_s=1e-6):
    """The servo stepped by ``step_s`` from ``start_m`` under ``goals`` [(from_s, m)] to
    ``t_end_s``."""
    x, t = start_m, 0.0
    while t < t_end_s - 1e-12:
        goal = [g for since, g in goals if since <= t + 1e-12][-1]
        x = goal - float(lag_error_after(goal - x, step_s, LAG_S, SPEED_M_S))
        t += step_s
    return x


@pytest.mark.parametrize("error_m", [1e-3, 3e-3, -8e-3])
def test_lag_error_after_is_the_limit_then_the_lag(error_m):
    """Within the knee (speed x lag, 2 mm) the lag; beyond, the speed limit until the knee."""
    for dt in (0.002, 0.02):
        assert fine(0.0, [(0.0, error_m)], dt) == pytest.approx(
            error_m - float(lag_error_after(error_m, dt, LAG_S, SPEED_M_S)), abs=1e-9
        )
    assert float(lag_error_after(1e-3, 0.01, LAG_S, np.inf)) == pytest.approx(
        1e-3 * np.exp(-0.01 / LAG_S)
    )
    assert float(lag_error_after(1e-3, 0.01, LAG_S, 0.0)) == 1e-3  # no speed: no motion


@pytest.mark.parametrize("error_m", [1e-3, 4e-3])
def test_one_integrator_step_ends_where_the_servo_does(error_m):
    """The lean model's one RK4 step of the lag towards the input (factor R = its Taylor
    polynomial) ends exactly where the speed-limited servo does over 10 ms."""
    dt, z = 0.01, -0.01 / LAG_S
    factor = 1 + z * (1 + z / 2 * (1 + z / 3 * (1 + z / 4)))
    rest, goal = np.array([0.40]), np.array([0.40 + error_m])
    u = lag_input(goal, rest, dt, LAG_S, SPEED_M_S, factor)
    stepped = u + (rest - u) * factor
    assert stepped[0] == pytest.approx(fine(0.40, [(0.0, 0.40 + error_m)], dt), abs=1e-9)
    assert np.array_equal(lag_input(goal, goal, dt, LAG_S, SPEED_M_S, factor), goal)


def test_a_read_is_taken_back_through_the_goals_in_effect():
    """A read 8 ms behind the filter, a goal step 3 ms before the filter's time: the rest
    length then is what the servo had, to a nanometre; the gain is the finite difference's."""
    goals = [(0.0, 0.4030), (0.005, 0.4005)]
    now = fine(0.40, goals, 0.008)
    then = fine(0.40, goals[:1], 0.0)
    config = SimpleNamespace(servo_lag_s=LAG_S, servo_speed_m_s=SPEED_M_S)
    history = [(t, np.array([g])) for t, g in goals]
    ekf = SimpleNamespace(t=0.008, goal_history=history, config=config)
    back, gain = rest_before(ekf, np.array([now]), 0.008)
    assert back[0] == pytest.approx(then, abs=1e-9)
    nudged, _ = rest_before(ekf, np.array([now + 1e-9]), 0.008)
    assert gain[0] == pytest.approx((nudged[0] - back[0]) / 1e-9, rel=1e-4)
    same, _ = taken_back(np.array([0.403]), np.array([0.403]), 0.008, LAG_S, SPEED_M_S)
    assert same[0] == 0.403  # a servo at its goal was there


def test_rendered_lengths_follow_the_servo_through_its_speed_limit():
    """Goals every 10 ms of a 0.14 m/s pull, faster than the lag follows within the limit: the
    lengths at uneven times are the finely stepped servo's."""
    t_cmd = np.arange(0.0, 0.1, 0.01)
    cmd = (0.40 - 0.14 * t_cmd)[:, None]
    t = np.array([0.0, 0.0033, 0.0101, 0.0457, 0.0999, 0.12])
    got = lagged(t_cmd, cmd, t, LAG_S, SPEED_M_S)[:, 0]
    goals = list(zip(t_cmd, cmd[:, 0], strict=True))
    expected = [fine(0.40, goals, ti) for ti in t]
    assert np.allclose(got, expected, rtol=0, atol=1e-9)
    assert not np.allclose(got, lagged(t_cmd, cmd, t, LAG_S)[:, 0], rtol=0, atol=1e-6)
