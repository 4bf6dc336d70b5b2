"""``python -m studies.control_compare``: SIL figures of the tilt maneuver, open
vs closed loop.

Truth: the scene with every wheel's J_3 scaled by ``--inertia-factor`` (default 1.2, a 20 %
error); planner: the nominal scene. Prints the target, plan times, the planner-vs-simulation
gap on the nominal model and the final tilt errors of open and closed loop.
"""

import argparse
import sys
import time

import numpy as np

from gyrohost.control.errors import PlanError, ScheduleError
from gyrohost.control.planner import Planner
from gyrohost.control.schedule import Limits
from gyrohost.control.sil import run_sil, scene_with_wheel_inertia, validate
from gyrohost.resources import shipped
from gyrotensegrity import Model, load_scene


def parse(argv):
    p = argparse.ArgumentParser(prog="python -m studies.control_compare", description=__doc__)
    p.add_argument("--scene", default=str(shipped("scene", "dbar-gyro")))
    p.add_argument("--target", type=float, default=-0.3, help="target tilt, rad")
    p.add_argument("--duration", type=float, default=4.0, help="maneuver length, s")
    p.add_argument("--max-speed", type=float, default=0.05, help="servo limit, m/s")
    p.add_argument("--knots", type=int, default=6)
    p.add_argument("--period", type=float, default=0.25, help="re-planning period, s")
    p.add_argument("--inertia-factor", type=float, default=1.2, help="truth J_3 / nominal")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--dop853", action="store_true", help="also validate with dop853 (slow)")
    p.add_argument("--save-schedule", help="write the first plan (.toml or .json)")
    return p.parse_args(argv)


def main(argv=None) -> int:
    a = parse(argv)
    try:
        nominal = Model(load_scene(a.scene))
        truth = Model(scene_with_wheel_inertia(a.scene, a.inertia_factor))
        planner = Planner(nominal, Limits(max_speed_m_s=a.max_speed), knots=a.knots)
    except (PlanError, ScheduleError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    knot_t = planner.knot_times(0.0, a.duration)
    times = []
    for _ in range(5):
        start = time.perf_counter()
        first = planner.plan_from_state(a.target, nominal.initial_state(), 0.0, knot_t)
        times.append(time.perf_counter() - start)
    print(
        f"target tilt            {a.target:+.4f} rad in {a.duration:g} s, "
        f"servo limit {a.max_speed:g} m/s, {a.knots} knots"
    )
    print(
        f"first plan             {first.message}; predicted {first.predicted_tilt_rad:+.5f} rad;"
        f" {1e3 * np.median(times):.1f} ms (median of 5), {first.n_eval} cost evaluations"
    )
    print(f"knots n1-n3            {np.array2string(first.knot_d_m, precision=4)} m")
    if a.save_schedule:
        print(f"saved                  {first.schedule.save(a.save_schedule)}")
    nominal_run = run_sil(nominal, planner, a.target, a.duration, closed_loop=False)
    print(
        f"plan vs RK4 sim        {nominal_run.final_tilt_rad:+.5f} rad (nominal model): "
        f"gap {nominal_run.final_tilt_rad - first.predicted_tilt_rad:+.2e} rad"
    )
    if a.dop853:
        at_land, settled = validate(first, nominal, planner, rtol=1e-8, atol=1e-10)
        print(
            f"plan vs dop853 sim     {at_land:+.5f} rad at landing, {settled:+.5f} rad 0.5 s "
            f"later: gap {at_land - first.predicted_tilt_rad:+.2e} rad"
        )
    runs = (("open loop          ", False, False), ("closed loop        ", True, False),
            ("closed loop + gain ", True, True))  # fmt: skip
    for name, closed, adapt in runs:
        r = run_sil(truth, planner, a.target, a.duration, closed, a.period, seed=a.seed,
                    adapt=adapt)  # fmt: skip
        pt = np.array([p.plan_time_s for p in r.plans])
        print(
            f"{name} J3 x {a.inertia_factor:g}: final tilt {r.final_tilt_rad:+.5f} rad, "
            f"error {r.error_rad:+.5f} rad, rate {r.final_rate_rad_s:+.1e} rad/s; "
            f"{len(pt)} plans, plan time mean {1e3 * pt.mean():.1f} ms max "
            f"{1e3 * pt.max():.1f} ms; {sum(not p.accepted for p in r.plans)} rejected; "
            f"gain {r.plans[-1].kappa:.3f}; sim wall {r.wall_time_s:.1f} s"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
