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
from gyrotensegrity import Model, Stepper, scene_from_dict, simulate
from gyrotensegrity.compat import tomllib


def scene_with_wheel_inertia(path, factor: float):
    """The scene file at ``path`` with every wheel's ``J_3`` scaled by ``factor``."""
    if not factor > 0.0:
        raise PlanError(f"wheel inertia factor must be positive, got {factor}")
    data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    for bar in data.get("bars", []):
        if "wheel" in bar:
            bar["wheel"]["radius"] *= math.sqrt(factor)
    data["scene"]["name"] = f"{data['scene'].get('name', 'scene')}-J3x{factor:g}"
    return scene_from_dict(data, f"{Path(path).name} (J3 x {factor:g})")


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
