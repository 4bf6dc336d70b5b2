"""The servos' motion: a first-order lag behind their goals, at most at their speed limit
(:func:`gyrohost.drivers.mx12.lag_error_after`), in the filter and in identification.

The process model steps the rest lengths by its integrator of a lag towards its input
(``servo_lag_s``: the RK4 substeps of the prediction step), which also carries the analytic and
compiled Jacobians. That integrator is not the lag's exponential (5 um
short over 10 ms of a 13 ms lag), and a servo that closes a large goal step at its speed limit
moves less than the lag would: the input is the goal the integrator needs to end the step
exactly where the servo does (:func:`step_input`), the goal itself to that integrator's error
while the lag alone holds. Identification renders the strings between the servos' reads by the
same motion (:func:`lagged`).
"""

import numpy as np

from gyrohost.drivers.mx12 import lag_error_after


def lag_input(goal_m, rest_m, dt_s: float, lag_s: float, speed_m_s: float, factor: float):
    """The input (alpha,) m that moves rest lengths ``rest_m`` over ``dt_s`` s as servos with
    goals ``goal_m``, lag ``lag_s`` and speed limit ``speed_m_s`` move them, for an integrator
    that leaves ``factor`` of a rest length's offset from its input (the exact lag's
    ``exp(-dt / lag)``; :meth:`.process_noise.ProcessNoise.lag_factor`)."""
    goal = np.asarray(goal_m, dtype=float)
    error = goal - rest_m
    if dt_s <= 0.0 or not error.any():
        return goal
    moved = error - lag_error_after(error, dt_s, lag_s, speed_m_s)
    return rest_m + moved / (1.0 - factor)


def taken_back(goal_m, rest_m, back_s: float, lag_s: float, speed_m_s: float):
    """Rest lengths (k,) m ``back_s`` s before they were ``rest_m`` on their way to ``goal_m``
    (the goal held), and d(that)/d(rest_m) (k,): :func:`~gyrohost.drivers.mx12.lag_error_after`
    backwards. Back in time the error grows along the lag, ``exp(back / lag)``, until it
    reaches ``speed lag`` (the knee) after ``lag ln(knee / |e|)``, and at the speed limit
    beyond."""
    goal = np.asarray(goal_m, dtype=float)
    error = goal - rest_m
    size, knee = np.abs(error), speed_m_s * lag_s
    with np.errstate(divide="ignore", invalid="ignore"):  # an error of 0 stays 0
        to_knee = np.where(size < knee, lag_s * np.log(knee / size), 0.0)
        grown = size * np.exp(np.minimum(back_s, to_knee) / lag_s)
        linear = np.maximum(back_s - to_knee, 0.0)
        back = grown + np.where(linear > 0.0, speed_m_s * linear, 0.0)  # no inf * 0
        gain = np.where(size >= knee, 1.0, np.where(linear > 0.0, knee / size, grown / size))
    gain = np.where(size > 0.0, gain, np.exp(back_s / lag_s))
    return goal - np.sign(error) * back, gain


def lagged(t_cmd_s, cmd_m, t_s, lag_s: float, speed_m_s: float = np.inf) -> np.ndarray:
    """Commands ``cmd_m`` (shape (kc, n), each held from its stamp ``t_cmd_s``) through a
    first-order lag ``lag_s`` (s) at most at ``speed_m_s`` (the servos' speed limit,
    :func:`~gyrohost.drivers.mx12.lag_error_after`), at times ``t_s`` (shape (k,)): shape
    (k, n); the servo starts at the first command.

    Exact for held commands: the position at each command's stamp from the one before, then
    at every time from the command in effect."""
    k = np.clip(np.searchsorted(t_cmd_s, t_s, "right") - 1, 0, None)
    if lag_s <= 0.0:
        return cmd_m[k]
    at_cmd = np.empty_like(cmd_m)
    y = at_cmd[0] = cmd_m[0]
    for i in range(1, len(t_cmd_s)):
        error = cmd_m[i - 1] - y
        y = cmd_m[i - 1] - lag_error_after(error, t_cmd_s[i] - t_cmd_s[i - 1], lag_s, speed_m_s)
        at_cmd[i] = y
    since = np.maximum(t_s - t_cmd_s[k], 0.0)[:, None]
    return cmd_m[k] - lag_error_after(cmd_m[k] - at_cmd[k], since, lag_s, speed_m_s)


def rest_before(ekf, rest_m, back_s: float):
    """The rest lengths (alpha,) m ``back_s`` s before ``ekf``'s time, where they are
    ``rest_m``, and d(those)/d(rest_m) (alpha,): taken back through each goal in effect
    meanwhile (``ekf.goal_history``; before its oldest, the oldest) by :func:`taken_back`."""
    c = ekf.config
    rest, gain = np.array(rest_m, dtype=float), np.ones(len(rest_m))
    now, then = ekf.t, ekf.t - back_s
    for since, goal in reversed(ekf.goal_history):
        start = max(since, then)
        if now > start:
            rest, g = taken_back(goal, rest, now - start, c.servo_lag_s, c.servo_speed_m_s)
            gain, now = gain * g, start
        if since <= then:
            break
    if now > then:  # older than the goals kept
        rest, g = taken_back(goal, rest, now - then, c.servo_lag_s, c.servo_speed_m_s)
        gain = gain * g
    return rest, gain


def step_input(ekf, dt_s: float) -> np.ndarray:
    """The input of ``ekf``'s prediction step of ``dt_s`` s: the held one, its rest lengths the
    goals the process model's lag needs to move them as the speed-limited servos do
    (:func:`lag_input`)."""
    c, alpha = ekf.config, ekf.model.alpha
    held = ekf.u[:alpha]
    factor = ekf.process.lag_factor(dt_s)
    goals = lag_input(held, ekf.x[ekf.layout.rest], dt_s, c.servo_lag_s, c.servo_speed_m_s, factor)
    if goals is held:
        return ekf.u
    u = ekf.u.copy()
    u[:alpha] = goals
    return u
