"""A planned tilt maneuver as the run loop plays it: open loop or re-planned from the EKF.

The run loop (``gyrotens run --target-tilt RAD``) builds a :class:`Maneuver` before anything
moves: the planner makes the first plan from the scene's initial state (the structure is at
rest before the maneuver), which the run checks against the servo limits like any schedule.
Open loop plays it. Closed loop hands every estimate to the :class:`.closed_loop.Replanner`,
which re-plans at its period and splices the result into the schedule being played.

Time here is schedule time: 0 when the run enters its ``schedule`` phase, in s.

Re-planning can run in a worker thread (``threaded=True``): :meth:`Maneuver.update` then
hands the estimate to the worker if it is idle and returns at once; the new schedule is taken
at the first update after the worker finished. A plan made from the estimate at ``t`` and
taken at ``t' > t`` is spliced at ``t'`` only if it is continuous there (it is: the planner
starts from the schedule in force, which the loop has been playing since ``t``).
"""

import threading
from dataclasses import asdict, dataclass

import numpy as np

from .closed_loop import Replanner
from .errors import PlanError
from .planner import Planner
from .schedule import Limits, Schedule


@dataclass(frozen=True)
class Target:
    """What ``gyrotens run --target-tilt`` asks for.

    Attributes
    ----------
    tilt_rad : float, rad
        Tilt of the D-bar plane to land at (``docs/schedule.md``, Attitude).
    duration_s : float, s
        Landing time after the start of the schedule.
    closed_loop : bool
        Re-plan from the estimate every ``period_s``; otherwise plan once and play.
    period_s : float, s
    knots : int
        Knot intervals of the plan.
    adapt : bool
        Fit the wheel-momentum gain while re-planning (``Replanner.adapt``).
    threaded : bool
        Re-plan in a worker thread instead of on the loop thread.
    reach_tolerance_rad : float, rad
        The first plan may land at most this far from ``tilt_rad``; farther, the target is out
        of reach and refused (:class:`Maneuver`).
    """

    tilt_rad: float
    duration_s: float = 4.0
    closed_loop: bool = False
    period_s: float = 0.25
    knots: int = 6
    adapt: bool = True
    threaded: bool = False
    reach_tolerance_rad: float = 0.005

    def __post_init__(self):
        if not np.isfinite(self.tilt_rad):
            raise PlanError(f"target tilt must be finite, got {self.tilt_rad}")
        if not self.reach_tolerance_rad > 0.0:
            raise PlanError(f"reach tolerance must be positive, got {self.reach_tolerance_rad} rad")
        if not (self.duration_s > 0.0 and self.period_s > 0.0):
            raise PlanError(
                f"duration ({self.duration_s} s) and re-planning period ({self.period_s} s) "
                "must be positive"
            )

    def to_dict(self) -> dict:
        return asdict(self)


class Maneuver:
    """The schedule of one tilt maneuver, planned and (closed loop) re-planned.

    Parameters
    ----------
    model : gyrotensegrity.Model
        The planner's model: the run's nominal scene (the EKF's model).
    limits : Limits
        Usually ``Limits.from_servos(config.servos.servo)``.
    target : Target

    Raises
    ------
    PlanError
        The scene is not a D-bar, no first plan within the limits, or the target is out of
        reach: the best plan lands more than ``target.reach_tolerance_rad`` from it (the
        message gives the tilts reachable in ``target.duration_s``).
    """

    def __init__(self, model, limits: Limits, target: Target):
        self.target = target
        self.planner = Planner(model, limits, knots=target.knots)
        self.replanner = Replanner(
            self.planner,
            target.tilt_rad,
            0.0,
            target.duration_s,
            target.period_s,
            adapt=target.adapt,
        )
        self.first = self.replanner.start(0.0, model.initial_state())
        self.landing_miss_rad = abs(self.first.predicted_tilt_rad - target.tilt_rad)
        if self.landing_miss_rad > target.reach_tolerance_rad:
            self._refuse_unreachable(model.initial_state())
        self._worker: threading.Thread | None = None
        self._lock = threading.Lock()
        self._ready: Schedule | None = None
        self._playing = self.first.schedule
        self.taken = 0
        """Re-planned schedules taken into the loop (threaded: at a later tick)."""

    def _refuse_unreachable(self, x0) -> None:
        planner, t = self.planner, self.target
        tilt, momentum, omega_w = planner.state_terms(x0, 0.0)
        knots = self.replanner.knot_t
        lo, hi = planner.reach(knots, 0.0, tilt, momentum, omega_w, planner.dbar.d_rest)
        raise PlanError(
            f"target tilt {t.tilt_rad:+.4f} rad is out of reach in {t.duration_s:g} s: within "
            f"the servo limits the plane lands between {lo:+.4f} and {hi:+.4f} rad (the best "
            f"plan lands at {self.first.predicted_tilt_rad:+.4f} rad, "
            f"{self.landing_miss_rad:.4f} rad off, more than {t.reach_tolerance_rad:g} rad); "
            "choose a target in that range or another duration"
        )

    @property
    def schedule(self) -> Schedule:
        return self.replanner.schedule

    @property
    def records(self) -> list:
        """:class:`.closed_loop.ReplanRecord` of every plan so far, the first included."""
        return self.replanner.records

    def update(self, t_s: float, x) -> Schedule:
        """Take the estimate ``x`` (a full state of the planner's model) at schedule time
        ``t_s`` (s); returns the schedule to play from now on. Open loop: the first plan."""
        if not self.target.closed_loop:
            return self.schedule
        if not self.target.threaded:
            before = self.replanner.schedule
            self.replanner.update(t_s, x)
            self.taken += self.replanner.schedule is not before
            return self.schedule
        return self._update_threaded(t_s, x)

    def _update_threaded(self, t_s: float, x) -> Schedule:
        with self._lock:
            ready, self._ready = self._ready, None
        if ready is not None:
            self._playing = ready
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
                "predicted_tilt_rad": self.first.predicted_tilt_rad,
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
            out["last_predicted_tilt_rad"] = recs[-1].predicted_tilt_rad
            out["kappa"] = recs[-1].kappa
        return out
