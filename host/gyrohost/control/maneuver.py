"""A planned maneuver as the run loop plays it: open loop or re-planned from the EKF.

The run loop (``gyrotens run --target-tilt RAD`` or ``--target-attitude R,P,Y``) builds a
:class:`Maneuver` before anything moves: the planner makes the first plan from the scene's
initial state (the structure is at rest before the maneuver), which the run checks against
the servo limits like any schedule. Open loop plays it. Closed loop hands every estimate to
the :class:`.closed_loop.Replanner`, which re-plans at its period and splices the result
into the schedule being played.

Time here is schedule time: 0 when the run enters its ``schedule`` phase, in s.

Re-planning can run in a worker thread (``threaded=True``): :meth:`Maneuver.update` then
hands the estimate to the worker if it is idle and returns at once; the new schedule is taken
at the first update after the worker finished. A plan made from the estimate at ``t`` and
taken at ``t' > t`` departs from what the loop played since ``t``: it is joined at ``t'`` by
the fastest move the limits allow onto it (:meth:`.schedule.Schedule.join`), so the servos never
jump.
"""

import threading
from dataclasses import asdict, dataclass

import numpy as np

from .attitude_planner import MODES, AttitudePlanner
from .closed_loop import Replanner
from .errors import PlanError
from .planner import Planner
from .schedule import Limits, Schedule
from .shape_attitude import AttitudeModel


@dataclass(frozen=True)
class Target:
    """What ``gyrotens run --target-tilt`` or ``--target-attitude`` asks for.

    Attributes
    ----------
    tilt_rad : float, rad, optional
        Tilt of the D-bar plane to land at (``docs/schedule.md``, Attitude).
    duration_s : float, s
        Landing time after the start of the schedule.
    closed_loop : bool
        Re-plan from the estimate every ``period_s``; otherwise plan once and play.
    period_s : float, s
    knots : int
        Knot intervals of the plan (default 6 for a tilt, 8 for an attitude).
    adapt : bool
        Fit the wheel-momentum gain while re-planning a tilt (``Replanner.adapt``).
    threaded : bool
        Re-plan in a worker thread instead of on the loop thread.
    reach_tolerance_rad : float, rad
        The first plan may land at most this far from the target; farther, the target is out
        of reach and refused (:class:`Maneuver`).
    attitude_rpy_rad : tuple of 3 float, rad, optional
        Instead of a tilt: roll, pitch, yaw of the scene's body frame to land at
        (docs/attitude-plans.md), planned on strings and wheels.
    mode : str
        With an attitude: ``both``, ``strings`` (wheels held) or ``wheels`` (rest lengths held).
    target_rest : dict, optional
        With an attitude: ``{string: rest length (m)}`` to land at (``--target-shape``,
        :mod:`.target_shape`); the scene's rest lengths where not given.
    actuator_lag_s : float, s
        How much later the servos and wheels follow a command than the plan assumes (their
        first-order lag): re-plans start from the commands they have reached
        (:class:`.closed_loop.Replanner`'s ``lag_s``).
    real_time : bool
        Re-plans beside a real-time loop (a run): an attitude re-plan's work is bounded by the
        period (:class:`.closed_loop.Replanner`'s ``real_time``). Off on a simulated clock, so
        that its plans do not depend on the machine.
    strings : tuple of str, optional
        With an attitude: the strings it moves (default: those the scene schedules,
        :class:`.shape_attitude.AttitudeModel`).
    """

    tilt_rad: float | None = None
    duration_s: float = 4.0
    closed_loop: bool = False
    period_s: float = 0.25
    knots: int | None = None
    adapt: bool = True
    threaded: bool = False
    reach_tolerance_rad: float = 0.005
    attitude_rpy_rad: tuple | None = None
    mode: str = "both"
    target_rest: dict | None = None
    actuator_lag_s: float = 0.0
    real_time: bool = False
    strings: tuple | None = None

    def __post_init__(self):
        if (self.tilt_rad is None) == (self.attitude_rpy_rad is None):
            raise PlanError("a target is a tilt or an attitude (roll, pitch, yaw), one of them")
        if self.tilt_rad is not None and not np.isfinite(self.tilt_rad):
            raise PlanError(f"target tilt must be finite, got {self.tilt_rad}")
        if self.attitude_rpy_rad is not None and not (
            len(self.attitude_rpy_rad) == 3 and np.isfinite(self.attitude_rpy_rad).all()
        ):
            raise PlanError(f"target attitude must be 3 finite angles, got {self.attitude_rpy_rad}")
        if self.knots is None:  # frozen: the default set once, here
            object.__setattr__(self, "knots", 6 if self.attitude_rpy_rad is None else 8)
        if self.mode not in MODES:
            raise PlanError(f"mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        if self.strings is not None and self.attitude_rpy_rad is None:
            raise PlanError("strings to move go with an attitude target, not a tilt")
        if self.target_rest and (self.attitude_rpy_rad is None or self.mode == "wheels"):
            raise PlanError("a target shape needs an attitude target whose strings move")
        if not 0.0 <= self.actuator_lag_s < self.period_s:
            raise PlanError(
                f"actuator lag must be at least 0 and shorter than the re-planning period "
                f"({self.period_s} s), got {self.actuator_lag_s} s"
            )
        if not self.reach_tolerance_rad > 0.0:
            raise PlanError(f"reach tolerance must be positive, got {self.reach_tolerance_rad} rad")
        if not (self.duration_s > 0.0 and self.period_s > 0.0):
            raise PlanError(
                f"duration ({self.duration_s} s) and re-planning period ({self.period_s} s) "
                "must be positive"
            )

    @property
    def value(self):
        """The tilt (rad) or the roll, pitch, yaw (rad) the re-planner steers toward."""
        return self.tilt_rad if self.attitude_rpy_rad is None else self.attitude_rpy_rad

    def to_dict(self) -> dict:
        out = asdict(self)
        if self.attitude_rpy_rad is not None:
            out["attitude_rpy_rad"] = [float(v) for v in self.attitude_rpy_rad]
        return out


def planner_for(model, limits: Limits, target: Target):
    """The tilt planner (a tilt) or the three-axis planner on the reduced attitude model."""
    if target.attitude_rpy_rad is None:
        return Planner(model, limits, knots=target.knots)
    reduced = AttitudeModel(model, target.strings, limits=limits)
    return AttitudePlanner(reduced, target.knots, mode=target.mode)


class Maneuver:
    """The schedule of one maneuver (tilt or attitude), planned and (closed loop) re-planned.

    Parameters
    ----------
    model : gyrotensegrity.Model
        The planner's model: the run's nominal scene (the EKF's model).
    limits : Limits
        Usually ``Limits.per_string(config.servos.servo)``.
    target : Target

    Raises
    ------
    PlanError
        A tilt on a scene that is not a D-bar, an attitude on a scene without a free body
        frame, no first plan within the limits, or the target is out of reach: the best plan
        lands more than ``target.reach_tolerance_rad`` from it (the message gives what is
        reachable in ``target.duration_s``).
    """

    def __init__(self, model, limits: Limits, target: Target):
        self.target, self.limits = target, limits
        self.planner = planner_for(model, limits, target)
        self.replanner = Replanner(
            self.planner,
            target.value,
            0.0,
            target.duration_s,
            target.period_s,
            adapt=target.adapt,
            target_rest=target.target_rest,
            lag_s=target.actuator_lag_s,
            real_time=target.real_time,
        )
        x0 = model.initial_state()
        self.first = self.replanner.start(0.0, x0)
        goal = self.replanner.goal
        self.landing_miss_rad = goal.miss(self.first)
        why = goal.refusal(
            self.first, x0, self.replanner.knot_t, target.duration_s, target.reach_tolerance_rad
        )
        if why is not None:
            raise PlanError(why)
        self._worker: threading.Thread | None = None
        self._lock = threading.Lock()
        self._ready: Schedule | None = None
        self._playing = self.first.schedule
        self.taken = 0
        """Re-planned schedules taken into the loop (threaded: at a later tick)."""

    @property
    def schedule(self) -> Schedule:
        return self.replanner.schedule

    @property
    def records(self) -> list:
        """:class:`.closed_loop.ReplanRecord` of every plan so far, the first included."""
        return self.replanner.records

    def update(self, t_s: float, x, now_s: float | None = None) -> Schedule:
        """Take the estimate ``x`` (a full state of the planner's model) at schedule time
        ``t_s`` (s); returns the schedule to play from now on (``now_s``, the loop's schedule
        time, default ``t_s``: the estimate trails the loop). Open loop: the first plan."""
        if not self.target.closed_loop:
            return self.schedule
        if not self.target.threaded:
            before = self.replanner.schedule
            self.replanner.update(t_s, x)
            self.taken += self.replanner.schedule is not before
            return self.schedule
        return self._update_threaded(t_s, x, t_s if now_s is None else max(t_s, now_s))

    def _update_threaded(self, t_s: float, x, now_s: float) -> Schedule:
        with self._lock:
            ready, self._ready = self._ready, None
            if ready is not None:
                # continuous from what was played since the estimate, and the next re-plan
                # starts from it (the worker that set ready no longer touches the schedule)
                self._playing = self._playing.join(ready, now_s, self.limits)
                self.replanner.schedule = self._playing
                self.taken += 1
        due = self.replanner.observe(t_s, x)
        idle = self._worker is None or not self._worker.is_alive()
        if due and idle:  # a re-plan still running makes the loop skip this one
            args = (t_s, np.array(x, float), self.replanner.fitted())
            self._worker = threading.Thread(target=self._replan, args=args, daemon=True)
            self._worker.start()
        return self._playing

    def _replan(self, t_s: float, x, fitted) -> None:
        # only this thread changes the replanner's schedule while the loop plays _playing
        plan = self.replanner.replan(t_s, x, fitted)
        if plan.success:
            with self._lock:
                self._ready = self.replanner.schedule

    def join(self, timeout_s: float = 1.0) -> None:
        """Wait for a running re-plan (end of the run)."""
        if self._worker is not None:
            self._worker.join(timeout_s)

    def summary(self) -> dict:
        """Target, first plan and re-planning figures (plan times in s)."""
        recs = self.records
        times = np.array([r.plan_time_s for r in recs[1:]]) if len(recs) > 1 else np.zeros(0)
        out = {
            "target": self.target.to_dict(),
            "first_plan": {
                **self.replanner.goal.summary(self.first),
                "landing_miss_rad": self.landing_miss_rad,
                "plan_time_s": self.first.plan_time_s,
                "message": self.first.message,
            },
            "replans": len(recs) - 1,
            "replans_accepted": sum(r.accepted for r in recs[1:]),
            "schedules_taken": self.taken,
        }
        if times.size:
            out["replan_time_mean_s"] = float(times.mean())
            out["replan_time_max_s"] = float(times.max())
            out["replan_time_median_s"] = float(np.median(times))
            out["replans_late"] = int(np.sum(times > self.target.period_s))
            if self.target.attitude_rpy_rad is None:
                out["last_predicted_tilt_rad"] = recs[-1].predicted_tilt_rad
                out["kappa"] = recs[-1].kappa
            else:
                out["last_predicted_error_rad"] = recs[-1].predicted_error_rad
        return out
