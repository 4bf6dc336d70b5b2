"""Software in the loop: open loop vs closed loop on a truth model with a wrong wheel inertia.

The truth is the D-bar scene with every wheel's spin inertia ``J_3`` scaled by a factor
(the radius scaled by its square root, so ``J_3 = m r^2 / 2`` scales exactly and the masses
stay); the planner's model is the nominal scene. The truth is stepped with RK4 (substeps of at
most ``max_dt_s``) under the schedule's rest lengths held over each control step of
``step_s`` (taken at the step's midpoint, as a servo moving continuously would give).
"""

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gyrohost.control.closed_loop import Replanner, TruthPlusNoise
from gyrohost.control.errors import PlanError
from gyrohost.control.planner import Plan, Planner
from gyrotensegrity import BodyFrame, Model, Stepper, scene_from_dict, simulate
from gyrotensegrity.compat import tomllib


def scene_with_wheel_inertia(path, factor: float):
    """The scene file at ``path`` with every wheel's ``J_3`` scaled by ``factor``."""
    data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    return scaled_scene(data, Path(path).name, wheel_inertia=factor)


def scaled_scene(data: dict, source: str, wheel_inertia=1.0, stiffness=1.0, damping=1.0):
    """The scene of the file contents ``data`` (a dict, changed in place) with every wheel's
    ``J_3`` (through its radius, so the masses stay), every string's stiffness and damping
    scaled by the factors: a truth whose parameters are off the model's."""
    factors = {"J3": wheel_inertia, "stiffness": stiffness, "damping": damping}
    for what, factor in factors.items():
        if not factor > 0.0:
            raise PlanError(f"{what} factor must be positive, got {factor}")
    for bar in data.get("bars", []):
        if "wheel" in bar:
            bar["wheel"]["radius"] *= math.sqrt(wheel_inertia)
    for string in data.get("strings", []):
        string["stiffness"] *= stiffness
        string["damping"] = string.get("damping", 0.0) * damping
    tag = ", ".join(f"{k} x {v:g}" for k, v in factors.items() if v != 1.0)
    name = data["scene"].get("name", "scene")
    data["scene"]["name"] = name + "".join(f"-{k}x{v:g}" for k, v in factors.items() if v != 1.0)
    return scene_from_dict(data, f"{source} ({tag or 'as is'})")


@dataclass(frozen=True)
class SilResult:
    """One SIL run.

    Attributes
    ----------
    t_s, tilt_rad : ndarray, shape (K,)
        Truth tilt at every control step.
    final_tilt_rad, final_rate_rad_s : float
        Truth tilt and tilt rate at the end (landing time plus the settling time).
    error_rad : float
        ``final_tilt_rad - target``.
    plans : list of ReplanRecord
    schedule : Schedule
        The schedule executed (spliced from all accepted plans).
    wall_time_s : float
    """

    t_s: np.ndarray
    tilt_rad: np.ndarray
    final_tilt_rad: float
    final_rate_rad_s: float
    error_rad: float
    plans: list
    schedule: object
    wall_time_s: float


def run_sil(
    truth: Model,
    planner: Planner,
    target_tilt_rad: float,
    duration_s: float,
    closed_loop: bool,
    period_s: float = 0.25,
    settle_s: float = 0.5,
    step_s: float = 0.01,
    max_dt_s: float = 2.5e-3,
    make_estimate=None,
    seed: int = 0,
    adapt: bool = True,
) -> SilResult:
    """Run one maneuver on ``truth``: plan once and play (open loop) or re-plan every
    ``period_s`` from an estimate (closed loop; ``adapt`` also fits the wheel-momentum gain,
    see :class:`.closed_loop.Replanner`).

    ``make_estimate(stepper) -> estimate`` builds the estimator on the truth stepper (the EKF
    plugs in here); ``estimate() -> (t_s, x)``. Default: :class:`TruthPlusNoise` with ``seed``.

    Both start from the same first plan, made at rest from the initial state (known: the
    structure is at rest before the maneuver)."""
    if truth.layout != planner.model.layout:
        raise PlanError("truth and planner models have different state layouts")
    start = time.perf_counter()
    stepper = Stepper(truth, max_dt=max_dt_s)
    estimate = (make_estimate or (lambda s: TruthPlusNoise(s, seed=seed)))(stepper)
    loop = Replanner(planner, target_tilt_rad, 0.0, duration_s, period_s, adapt=adapt)
    loop.start(0.0, stepper.x)  # planned at rest, before the maneuver: the state is known
    n = int(round((duration_s + settle_s) / step_s))
    t, tilt = [0.0], [planner.attitude.tilt(truth.nodes(stepper.x)[0])]
    for _ in range(n):
        schedule = loop.update(*estimate()) if closed_loop else loop.schedule
        stepper.step(step_s, schedule.input_at(truth, stepper.t + 0.5 * step_s))
        t.append(stepper.t)
        tilt.append(planner.attitude.tilt(truth.nodes(stepper.x)[0]))
    N, N_dot = truth.nodes(stepper.x)
    return SilResult(
        t_s=np.array(t),
        tilt_rad=np.array(tilt),
        final_tilt_rad=tilt[-1],
        final_rate_rad_s=planner.attitude.tilt_rate(N, N_dot),
        error_rad=tilt[-1] - target_tilt_rad,
        plans=loop.records,
        schedule=loop.schedule,
        wall_time_s=time.perf_counter() - start,
    )


def validate(plan: Plan, model: Model, planner: Planner, settle_s=0.5, rtol=1e-9, atol=1e-11):
    """Tilt (rad) of the accurate simulation (dop853) of ``plan`` on ``model`` at the landing
    time and ``settle_s`` later; returns ``(tilt_at_landing, tilt_after_settling)``."""
    schedule = plan.schedule
    t_land = schedule.t_end
    run = simulate(
        model,
        duration=t_land + settle_s,
        integrator="dop853",
        rtol=rtol,
        atol=atol,
        sample_dt=0.05,
        control=lambda t, x, u, params: schedule.input_at(params, t),
    )
    k = int(np.argmin(np.abs(run["t"] - t_land)))
    return planner.attitude.tilt(run["N"][k]), planner.attitude.tilt(run["N"][-1])


@dataclass(frozen=True)
class ManeuverSil:
    """One SIL run of a :class:`.maneuver.Maneuver` (tilt or attitude).

    Attributes
    ----------
    t_s : ndarray, shape (K,), s
    quaternion : ndarray, shape (K, 4)
        The truth's body attitude (its ``[attitude]`` frame) at every control step.
    wheel_speed_rad_s : ndarray, shape (K, n_w)
        The truth's wheel spins.
    rest_length_m : ndarray, shape (K, s)
        The scheduled rest lengths played over each step (at its midpoint).
    landing_index : int
        The step at the landing time.
    schedule : Schedule
        The schedule played (spliced from the accepted re-plans).
    records : list of ReplanRecord
    wall_time_s : float
    """

    t_s: np.ndarray
    quaternion: np.ndarray
    wheel_speed_rad_s: np.ndarray
    rest_length_m: np.ndarray
    landing_index: int
    schedule: object
    records: list
    wall_time_s: float


def run_maneuver_sil(
    truth: Model,
    maneuver,
    settle_s=0.5,
    step_s=0.01,
    max_dt_s=5e-4,
    seed=0,
    fast=False,
    noise=(1e-3, 2e-3),
    actuator_lag_s=0.0,
) -> ManeuverSil:
    """Play ``maneuver`` (open loop, or re-planned from the truth plus noise,
    :class:`TruthPlusNoise` with ``seed`` and ``noise``: the std of the node coordinates, m,
    and of their rates, m/s) on ``truth`` in simulated time; the truth's rest lengths and
    wheel speeds follow the schedule at once, or through a first-order lag ``actuator_lag_s``
    (s) as the rig's servos and wheels do.

    The truth's first states are the planner model's layout (a rig-fidelity truth appends its
    own at the end, docs/rig-fidelity.md); the estimate is the truth's cut to it. Scheduled
    wheels are torque-driven in the truth, each by an ideal speed loop: over every control
    step the torque ``J_3 (omega_cmd(t + h) - omega) / h`` that brings its spin to the
    command at the step's end, whose reaction a rig-fidelity truth puts on the bar.
    """
    nominal = maneuver.planner.model
    nominal = getattr(nominal, "model", nominal)  # the attitude planner's full model
    n_x = nominal.layout.size
    if truth.layout.size - truth.layout.n_rig != n_x or truth.layout.m != nominal.layout.m:
        raise PlanError("truth and planner models have different state layouts")
    start = time.perf_counter()
    stepper = Stepper(truth, max_dt=max_dt_s, fast=fast)
    estimate = TruthPlusNoise(stepper, *noise, seed=seed)
    frame = BodyFrame.of_model(truth)
    t_end = maneuver.schedule.t_end
    n = int(round((t_end + settle_s) / step_s))
    rows = []
    actuators = Actuators(actuator_lag_s)
    for _ in range(n):
        t = stepper.t
        t_est, x = estimate()
        schedule = maneuver.update(t_est, x[:n_x])
        u = _truth_input(truth, schedule, stepper.x, t, step_s, actuators)
        rows.append((t, frame.attitude(truth.nodes(stepper.x)[0]).quaternion,
                     truth.wheel_speeds(stepper.x, u), schedule(t + 0.5 * step_s)))  # fmt: skip
        stepper.step(step_s, u)
    t_s = np.array([r[0] for r in rows])
    return ManeuverSil(
        t_s=t_s,
        quaternion=np.array([r[1] for r in rows]),
        wheel_speed_rad_s=np.array([r[2] for r in rows]),
        rest_length_m=np.array([r[3] for r in rows]),
        landing_index=int(np.argmin(np.abs(t_s - t_end))),
        schedule=maneuver.schedule,
        records=maneuver.records,
        wall_time_s=time.perf_counter() - start,
    )


class Actuators:
    """What the truth's servos and wheels reach of the schedule's commands: the commands, or
    with ``lag_s`` > 0 their first-order lag ``y += (1 - exp(-h / lag_s)) (u - y)`` per step
    ``h`` (exact for a command held over the step), starting at the first command."""

    def __init__(self, lag_s: float = 0.0):
        self.lag_s = float(lag_s)
        self._reached: dict = {}

    def follow(self, kind: str, command, h: float):
        """The ``kind`` (rest lengths or spins) reached after ``h`` s of ``command``."""
        last = self._reached.get(kind)
        if self.lag_s > 0.0 and last is not None:
            command = last + (1.0 - np.exp(-h / self.lag_s)) * (command - last)
        self._reached[kind] = command
        return command


def _truth_input(truth, schedule, x, t, h, actuators):
    """The truth's input over ``[t, t + h]``: the scheduled rest lengths at the midpoint, the
    scheduled wheels' speed-loop torques (see :func:`run_maneuver_sil`), as ``actuators``
    reach them."""
    u = truth.input_at(t + 0.5 * h)
    u[schedule.bind(truth)] = actuators.follow("rest", schedule(t + 0.5 * h), h)
    if schedule.wheels:
        k = np.asarray(schedule.bind_wheels(truth), int)
        if not np.isin(k, truth.torque_wheels).all():
            raise PlanError("run_maneuver_sil: the truth's scheduled wheels must be torque-driven")
        omega = truth.wheel_speeds(x, u)[k]
        J3 = truth.J3[truth.wheel_bars[k]]
        spins = actuators.follow("spins", schedule.wheel_speeds(t + h), h)
        u[truth.alpha + k] = J3 * (spins - omega) / h
    return u
