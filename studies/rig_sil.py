"""SIL on the simulated rig with the EKF: open vs closed loop under a wheel-inertia error.

``python -m studies.rig_sil [--config RIG.toml] [-o DIR] [--thread]`` runs the
maneuver twice on the simulated rig in real time (``gyrotens run --sim --target-tilt``): the
truth's wheels have ``J_3`` times ``--inertia-scale`` (``[sim.truth] wheel_inertia_scale``),
the planner and the EKF the nominal scene. Open loop plays the first plan; closed loop
re-plans from the EKF's estimate. Prints target, the truth's tilt error after settling (from
the ``truth`` stream), re-plans, plan times and loop timing of each.
"""

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np


def mismatched(config, inertia_scale: float):
    """``config`` with the truth's wheel inertia scaled (the planner and EKF keep the scene)."""
    from gyrohost.simrig.config import with_sim_keys

    return with_sim_keys(config, "truth", wheel_inertia_scale=inertia_scale)


def settled_tilt(folder) -> tuple[float, float]:
    """Truth tilt (rad) at the end of the settle phase and that time (host s), from the log."""
    from gyrohost.run.log import read_stream

    events = read_stream(folder, "events")
    kinds, times = list(events["kind"]), np.asarray(events["t_s"], float)
    t_end = float(times[kinds.index("end")])
    truth = read_stream(folder, "truth")
    k = int(np.searchsorted(np.asarray(truth["t_s"], float), t_end, side="right")) - 1
    return float(truth["tilt_rad"][k]), t_end


def loop_figures(folder) -> dict:
    """Wall time per tick in the schedule phase (median, p99, max; s) and overruns."""
    from gyrohost.run.log import read_stream

    loop = read_stream(folder, "loop")
    in_schedule = np.asarray(loop["phase"]) == "schedule"
    work = np.asarray(loop["work_s"], float)[in_schedule]
    late = np.asarray(loop["late_s"], float)[in_schedule]
    return {
        "work_p50_s": float(np.median(work)),
        "work_p99_s": float(np.percentile(work, 99)),
        "work_max_s": float(np.max(work)),
        "late_max_s": float(np.max(late)),
        "overruns": int(np.sum(late > 0.01)),
        "ticks": int(in_schedule.sum()),
    }


def run_case(config, out, target, closed_loop: bool, threaded: bool = False) -> dict:
    """One run of the maneuver on the simulated rig; its figures."""
    from gyrohost.control.maneuver import Maneuver
    from gyrohost.control.schedule import Limits
    from gyrohost.run import run_simulated
    from gyrotensegrity import Model, load_scene

    target = replace(target, closed_loop=closed_loop, threaded=threaded)
    maneuver = Maneuver(
        Model(load_scene(config.scene_path)), Limits.per_string(config.servos.servo), target
    )
    result = run_simulated(config, maneuver, out)
    if not result.completed:
        raise RuntimeError(f"{out}: run did not complete: {result.reason}")
    tilt, _ = settled_tilt(out)
    s = result.summary
    return {
        "log": str(out),
        "final_tilt_rad": tilt,
        "error_rad": tilt - target.tilt_rad,
        "maneuver": s["maneuver"],
        "loop": loop_figures(out),
        "loop_summary": s["loop"],
    }


def compare(config, out_dir, target, threaded: bool = False) -> dict:
    """Open and closed loop on ``config`` (already mismatched), logs into ``out_dir``."""
    out_dir = Path(out_dir)
    return {
        "target": target.to_dict(),
        "open": run_case(config, out_dir / "open", target, False),
        "closed": run_case(config, out_dir / "closed", target, True, threaded),
    }


def report(result: dict, inertia_scale: float) -> str:
    """The figures as text."""
    t = result["target"]
    lines = [
        f"target {t['tilt_rad']:+.4f} rad landing at {t['duration_s']:g} s; truth wheel "
        f"inertia x {inertia_scale:g}; planner and EKF nominal; re-plan every {t['period_s']} s",
        f"{'':8}{'final tilt':>12}{'error':>10}{'re-plans':>10}{'plan ms mean/max':>18}"
        f"{'tick ms p50/p99/max':>22}{'overruns':>10}",
    ]
    for name in ("open", "closed"):
        c = result[name]
        m, lp = c["maneuver"], c["loop"]
        plans = (
            f"{1e3 * m['replan_time_mean_s']:.1f}/{1e3 * m['replan_time_max_s']:.1f}"
            if m["replans"]
            else f"{1e3 * m['first_plan']['plan_time_s']:.1f} (once)"
        )
        ticks = "/".join(f"{1e3 * lp[k]:.1f}" for k in ("work_p50_s", "work_p99_s", "work_max_s"))
        lines.append(
            f"{name:8}{c['final_tilt_rad']:>+12.4f}{c['error_rad']:>+10.4f}{m['replans']:>10}"
            f"{plans:>18}{ticks:>22}{lp['overruns']:>10}"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    from gyrohost.config import load_rig_config
    from gyrohost.control.maneuver import Target
    from gyrohost.resources import shipped

    p = argparse.ArgumentParser(prog="python -m studies.rig_sil", description=__doc__)
    p.add_argument("--config", type=Path, default=shipped("config", "sim-rig"))
    p.add_argument("-o", "--out", type=Path, default=Path("out/rig-sil"))
    p.add_argument("--target", type=float, default=-0.3, help="target tilt, rad")
    p.add_argument("--duration", type=float, default=4.0, help="landing time, s")
    p.add_argument("--inertia-scale", type=float, default=1.2)
    p.add_argument("--thread", action="store_true", help="re-plan in a worker thread")
    a = p.parse_args(argv)
    for sub in ("open", "closed"):
        if (a.out / sub / "meta.json").exists():
            print(f"error: {a.out / sub} already holds a log; choose another -o", file=sys.stderr)
            return 2
    config = mismatched(load_rig_config(a.config), a.inertia_scale)
    result = compare(config, a.out, Target(a.target, a.duration), a.thread)
    text = report(result, a.inertia_scale)
    print(text)
    (a.out / "summary.json").write_text(json.dumps(result, indent=2) + "\n")
    (a.out / "summary.txt").write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
