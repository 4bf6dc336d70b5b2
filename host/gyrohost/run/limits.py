"""Limits of a run: the schedule against the servos before anything moves, and the measured and
estimated values every tick of the run."""

import math

import numpy as np

from gyrohost.config import RunTable
from gyrohost.control.schedule import Limits, Schedule
from gyrohost.estimator.ekf import Status
from gyrohost.run.errors import LimitBreach, RunError, ScheduleRefused


def check_schedule(schedule: Schedule, servos, run=None, max_s: float = math.inf) -> None:
    """Refuse a schedule that breaks any servo's or wheel limit or lasts longer than ``max_s``
    seconds (before anything moves).

    Each scheduled string must be wound by a configured servo; its rest lengths must lie in
    that servo's ``[min_length_m, max_length_m]`` and change no faster than ``max_speed_m_s``.
    Each scheduled wheel speed must stay within ``run.max_wheel_speed_rad_s`` (the rig
    configuration's ``[run]`` table, a :class:`gyrohost.config.RunTable`; default: its
    defaults).

    Raises
    ------
    ScheduleRefused
        Naming the string or wheel, the value and the limit.
    """
    by_string = {s.string or s.name: s for s in servos}
    problems = []
    for i, name in enumerate(schedule.names):
        servo = by_string.get(name)
        if servo is None:
            problems.append(f"{name}: no servo winds this string (servos: {sorted(by_string)})")
            continue
        one = Schedule((name,), schedule.t, schedule.rest_length[:, [i]], schedule.name)
        problems += one.problems(Limits.from_servos([servo]))
    problems += wheel_problems(schedule, run or RunTable())
    if schedule.t_end > max_s:
        problems.append(
            f"it lasts {schedule.t_end:g} s, more than the {max_s:g} s a run may play "
            "(gyrotens run --max-duration S allows longer)"
        )
    if problems:
        raise ScheduleRefused(
            f"schedule {schedule.name} refused, nothing moved: " + "; ".join(problems)
        )


def wheel_problems(schedule: Schedule, run) -> list[str]:
    """The scheduled wheel speeds beyond ``run.max_wheel_speed_rad_s``, as messages."""
    limit = run.max_wheel_speed_rad_s
    out = []
    for name, col in zip(schedule.wheels, schedule.wheel_speed.T, strict=True):
        k = int(np.argmax(np.abs(col)))
        if abs(col[k]) > limit:
            out.append(
                f"wheel on {name}: speed {col[k]:.4g} rad/s at t = {schedule.t[k]:g} s beyond "
                f"[run] max_wheel_speed_rad_s = {limit:g} rad/s"
            )
    return out


class CommandHistory:
    """The largest wheel command in force over a stretch of time (the wheel-speed limit's
    reference: after a step down the board ramps and the wheels follow with their lag, so a
    telemetry frame is compared with what was commanded over the ``memory_s`` before it).

    Parameters
    ----------
    memory_s : float, s
    keep_s : float, s
        History kept (a frame received late by a starved loop still finds its commands).
    """

    def __init__(self, memory_s: float, keep_s: float = 60.0):
        self.memory_s, self.keep_s = memory_s, keep_s
        self.items: list[tuple[float, float]] = []

    def add(self, t_s: float, value: float) -> None:
        """``value`` is commanded from ``t_s`` on."""
        if not self.items or self.items[-1][1] != value:
            self.items.append((t_s, value))
        while len(self.items) > 1 and self.items[1][0] < t_s - self.keep_s:
            self.items.pop(0)

    def peak_before(self, t_s: float) -> float:
        """The largest command in force between ``t_s - memory_s`` and now."""
        since = t_s - self.memory_s
        first = max([k for k, (t, _) in enumerate(self.items) if t <= since], default=0)
        return max(v for _, v in self.items[first:])


def check_limits(settings, omega_cmd, wheel_telemetry, servo_states, tilt_rad, ekf) -> None:
    """Raise if a value of this tick is beyond its limit.

    Parameters
    ----------
    settings : RunSettings
    omega_cmd : float or ndarray, rad/s
        Commanded wheel speeds (the largest command in force over the telemetry's last
        second: :meth:`CommandHistory.peak_before`).
    wheel_telemetry : WheelTelemetry sample or None
        The newest wheel-board telemetry.
    servo_states : list of ServoState
        The newest servo read-back.
    tilt_rad : float
        The estimated plane tilt (NaN without an estimate or an attitude measure: unchecked).
    ekf : TensegrityEKF or None

    Raises
    ------
    LimitBreach
        Wheel speed, servo load or tilt beyond its limit.
    RunError
        The estimator has only predictions left (every source timed out).
    """
    s = settings
    if wheel_telemetry is not None:
        limit = np.max(np.abs(omega_cmd)) + s.wheel_speed_margin_rad_s
        fast = np.max(np.abs(wheel_telemetry.omega_rad_s))
        if fast > limit:
            raise LimitBreach(f"wheel speed {fast:.2f} rad/s above the limit {limit:.2f} rad/s")
    for state in servo_states:
        if abs(state.load_fraction) > s.max_servo_load:
            raise LimitBreach(
                f"servo '{state.name}' load {state.load_fraction:.2f} above the limit "
                f"{s.max_servo_load:g}"
            )
    if not math.isnan(tilt_rad) and abs(tilt_rad) > s.max_tilt_rad:
        raise LimitBreach(
            f"estimated tilt {tilt_rad:.3f} rad beyond the limit {s.max_tilt_rad:g} rad"
        )
    if ekf is not None and ekf.status & Status.PREDICTION_ONLY:
        raise RunError(f"estimator fault: every source timed out (status {ekf.status!r})")
