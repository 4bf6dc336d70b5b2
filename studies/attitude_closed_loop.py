"""``python -m studies.attitude_closed_loop``: three-axis attitude maneuvers of the D-bar, open
loop against closed loop (re-planned every 0.25 s), on a truth whose parameters are off by the
identification's reported 1-sigma (J3 +0.5 %, string stiffness +5 %, damping +14 %).

Two parts:

- ``sil`` (simulated clock): the truth is dbar-rig, the rig-fidelity D-bar (hinges, stators,
  the motors' reaction: a wheel's speed change turns the structure, as the planner's momentum
  balance says), with dbar-gyro's n2-n4 follower string as the planner's model assumes, its
  scheduled wheels torque-driven by an ideal speed loop (``sil.run_maneuver_sil``). The
  estimate is the truth plus white noise on the nodes (:data:`NOISE`). Strings and wheels, wheels
  only, strings only, over targets inside the D-bar's reachable set ``tan(yaw) = tan(roll) /
  sin(pitch)`` (strings alone: turns about the momentum, the pitch axis). :data:`NOISE`
  gives the stand-in estimate the EKF's accuracy.
- ``rig`` (real time, EKF in the loop): ``gyrotens run --sim --target-attitude`` on the
  simulated rig (sim-rig) with the truth scene dbar-gyro off by the same 1-sigma. Strings only:
  the simulated rig's wheels are speed-controlled without the motors' reaction (the rig-fidelity
  truth needs the reference path, about real time on one core at its stability step, and
  torque-driven wheels), so on it a wheel's speed change does not turn the structure.

Prints per case: target, mode, loop, landing error (geodesic, deg, truth at the landing time),
peak wheel speed, servo travel, re-plans (accepted) and their time (median, worst, ms), whether
the schedule and the truth stayed within the limits. Writes an attitude and command figure of
the heavier-wheeled case to ``--out``.
"""

import argparse
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from gyrohost.control import Limits, PlanError
from gyrohost.control.attitude_planner import target_quaternion
from gyrohost.control.maneuver import Maneuver, Target
from gyrohost.control.sil import run_maneuver_sil, scaled_scene
from gyrohost.resources import shipped
from gyrotensegrity import Model, load_scene
from gyrotensegrity.attitude import angle_between, euler_zyx
from gyrotensegrity.compat import tomllib

ONE_SIGMA = {"wheel_inertia": 1.005, "stiffness": 1.05, "damping": 1.14}
"""The identification's reported 1-sigma (reports/identification.md), as truth factors."""
NOISE = (1e-4, 1.5e-4)
"""The SIL estimate's noise, as the EKF's on the real-time rig: node coordinates 0.1 mm (its
node error RMS, 0.09 mm, ``gyrotens run --sim``), node rates 0.15 mm/s (the gyro's 6.9e-4
rad/s per 100 Hz sample, sim-rig's ``imu_rate_std_rad_s``, on nodes 0.216 m from the
centre)."""


def on_the_reachable_set(roll_deg, pitch_deg):
    """Roll, pitch and the yaw of ``tan(yaw) = tan(roll) / sin(pitch)``, deg."""
    yaw = math.atan(math.tan(math.radians(roll_deg)) / math.sin(math.radians(pitch_deg)))
    return (roll_deg, pitch_deg, round(math.degrees(yaw), 2))


THREE_AXIS_DEG = tuple(
    on_the_reachable_set(*rp) for rp in ((10.0, -20.0), (-10.0, -15.0), (5.0, 30.0))
)
"""Targets needing all three axes, on the D-bar's reachable set."""
PITCH_DEG = ((0.0, -10.0, 0.0), (0.0, -15.0, 0.0))
"""Strings-only targets: turns about the momentum (the pitch axis)."""
CASES = [("both", t) for t in THREE_AXIS_DEG] + [("wheels", t) for t in THREE_AXIS_DEG]
CASES += [("strings", t) for t in PITCH_DEG]


def parse(argv):
    p = argparse.ArgumentParser(prog="python -m studies.attitude_closed_loop", description=__doc__)
    p.add_argument("--part", choices=("sil", "rig", "both"), default="both")
    p.add_argument("--duration", type=float, default=4.0, help="landing time, s")
    p.add_argument("--cases", type=int, default=len(CASES), help="the first N sil cases")
    p.add_argument("-o", "--out", type=Path, default=Path("out/attitude-closed-loop"))
    return p.parse_args(argv)


def truth_data(name):
    return tomllib.loads(shipped("scene", name).read_text())


STRESS_J3 = 1.05
"""A heavier truth's wheels (x 1.05, ten times the 1-sigma) for one more case: what closed loop
corrects when the model is clearly wrong."""


def rig_truth(**factors):
    """dbar-rig with the follower string, off by ``factors`` (default 1-sigma), its wheels'
    torques the SIL's."""
    data = truth_data("dbar-rig")
    for bar in data["bars"]:
        bar["wheel"].pop("torque")
    data["strings"].append(dict(data["strings"][0], name="s24", nodes=["n2", "n4"]))
    return Model(scaled_scene(data, "dbar-rig with s24", **(ONE_SIGMA | factors)))


def within_limits(run, limits) -> bool:
    """The played schedule, the truth's wheels and the rest lengths played, inside the limits."""
    ok = not run.schedule.problems(limits)
    ok &= bool(np.max(np.abs(run.wheel_speed_rad_s)) <= limits.max_wheel_speed_rad_s)
    for name, column in zip(run.schedule.names, run.rest_length_m.T, strict=True):
        low, high = limits.range_of(name)
        ok &= bool(low <= column.min() and column.max() <= high)
    return ok


def replan_times_ms(records):
    times = np.array([r.plan_time_s for r in records[1:]]) * 1e3
    if not times.size:
        return "-"
    return f"{np.median(times):.0f}/{times.max():.0f}"


def sil_case(nominal, truth, mode, target_deg, closed, a):
    limits = Limits()
    target = Target(attitude_rpy_rad=tuple(np.radians(target_deg)), duration_s=a.duration,
                    closed_loop=closed, mode=mode)  # fmt: skip
    maneuver = Maneuver(nominal, limits, target)
    run = run_maneuver_sil(truth, maneuver, max_dt_s=2e-3, noise=NOISE)
    q = target_quaternion(np.radians(target_deg))
    error = math.degrees(angle_between(q, run.quaternion[run.landing_index]))
    travel = np.ptp(run.schedule.rest_length, axis=0) * 1e3 if run.schedule.names else [0.0]
    accepted = sum(r.accepted for r in run.records[1:])
    line = (
        f"{mode:8s}{', '.join(f'{v:+.1f}' for v in target_deg):>22s}"
        f"{'closed' if closed else 'open':>8s}{error:>9.3f}"
        f"{np.max(np.abs(run.wheel_speed_rad_s)):>9.1f}{max(travel):>9.1f}"
        f"{f'{len(run.records) - 1} ({accepted})':>10s}{replan_times_ms(run.records):>11s}"
        f"{'yes' if within_limits(run, limits) else 'NO':>7s}"
    )
    return line, run, error


def sil_part(a):
    nominal = Model(load_scene(shipped("scene", "dbar-gyro")))
    truth = rig_truth()
    print(f"sil: truth {truth.scene.source}, planner dbar-gyro, landing at {a.duration:g} s")
    print(
        f"{'mode':8s}{'target r, p, y (deg)':>22s}{'loop':>8s}{'err deg':>9s}{'wheel':>9s}"
        f"{'servo mm':>9s}{'re-plans':>10s}{'ms med/max':>11s}{'limits':>7s}"
    )
    errors, times, figure_runs = [], [], {}
    for mode, target_deg in CASES[: a.cases]:
        for closed in (False, True):
            try:
                line, run, error = sil_case(nominal, truth, mode, target_deg, closed, a)
            except PlanError as exc:
                print(f"{mode:8s}{', '.join(f'{v:+.1f}' for v in target_deg):>22s}  {exc}")
                break
            print(line, flush=True)
            if closed and mode != "strings":
                errors.append(error)
                times += [r.plan_time_s for r in run.records[1:]]
    if errors:
        print(
            f"three-axis targets, closed loop: landing error at most {max(errors):.3f} deg; "
            f"{len(times)} re-plans, median {1e3 * np.median(times):.0f} ms, worst "
            f"{1e3 * max(times):.0f} ms, {sum(t > 0.25 for t in times)} longer than 0.25 s"
        )
    if a.cases:
        stressed = rig_truth(wheel_inertia=STRESS_J3)
        print(f"the same, truth {stressed.scene.source}:")
        for closed in (False, True):
            line, figure_runs[closed], _ = sil_case(nominal, stressed, *CASES[0], closed, a)
            print(line, flush=True)
    if figure_runs:
        path = plot(figure_runs, CASES[0][1], a.out / "attitude-closed-loop.png")
        print(f"figure: {path}")


def plot(runs, target_deg, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    for closed, run in runs.items():
        rpy = np.degrees([euler_zyx(_matrix(q)) for q in run.quaternion])
        style = "-" if closed else ":"
        for i, name in enumerate(("roll", "pitch", "yaw")):
            axes[0].plot(run.t_s, rpy[:, i], style, color=f"C{i}",
                         label=f"{name} {'closed' if closed else 'open'}")  # fmt: skip
        axes[1].plot(run.t_s, run.rest_length_m[:, 0] * 1e3, style, color="C0")
        axes[2].plot(run.t_s, run.wheel_speed_rad_s, style)
    for i, v in enumerate(target_deg):
        axes[0].axhline(v, color=f"C{i}", lw=0.5)
    axes[0].set_ylabel("truth attitude, deg")
    axes[0].legend(ncol=2, fontsize=7)
    axes[1].set_ylabel("s13 rest length, mm")
    axes[2].set_ylabel("truth wheel speeds, rad/s")
    axes[2].set_xlabel("t, s (dotted: open loop, solid: closed loop)")
    fig.suptitle(f"D-bar to roll, pitch, yaw {target_deg} deg, truth's wheels 5 % heavier")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _matrix(q):
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(q, scalar_first=True).as_matrix()


def rig_part(a):
    """Real time on the simulated rig, EKF in the loop, strings only."""
    from gyrohost.config import load_rig_config
    from gyrohost.ident.scenefile import scene_toml
    from gyrohost.run import run_simulated
    from gyrohost.simrig.config import with_truth_scene

    a.out.mkdir(parents=True, exist_ok=True)
    scene = scaled_scene(truth_data("dbar-gyro"), "dbar-gyro", **ONE_SIGMA)
    truth_path = a.out / "truth-dbar-gyro-1sigma.toml"
    truth_path.write_text(scene_toml(scene, "dbar-gyro, parameters 1-sigma off"))
    config = with_truth_scene(load_rig_config(shipped("config", "sim-rig")), truth_path)
    limits = Limits.per_string(config.servos.servo)
    print(f"rig (real time, EKF): truth {scene.source}, strings only, re-planned in a thread")
    for target_deg in PITCH_DEG:
        for closed in (False, True):
            target = Target(attitude_rpy_rad=tuple(np.radians(target_deg)),
                            duration_s=a.duration, mode="strings")  # fmt: skip
            target = replace(target, closed_loop=closed, threaded=closed)
            out = a.out / f"rig-{target_deg[1]:+g}-{'closed' if closed else 'open'}"
            maneuver = Maneuver(Model(load_scene(config.scene_path)), limits, target)
            start = time.perf_counter()
            result = run_simulated(config, maneuver, out)
            print(rig_line(target_deg, closed, result, time.perf_counter() - start), flush=True)


def rig_line(target_deg, closed, result, wall_s):
    s = result.summary
    m = s["maneuver"]
    error = s.get("attitude_end_truth_error_rad", math.nan)
    lag = s.get("rig_real_time", {})
    times = (
        f"{1e3 * m['replan_time_median_s']:.0f}/{1e3 * m['replan_time_max_s']:.0f} ms, "
        f"{m['replans_late']} late"
        if m["replans"]
        else "-"
    )
    return (
        f"  target {', '.join(f'{v:+.1f}' for v in target_deg)} deg "
        f"{'closed' if closed else 'open'}: {s['reason']}; truth {math.degrees(error):.3f} deg "
        f"off at the landing; re-plans {m['replans']} ({m['replans_accepted']} accepted), "
        f"{times}; loop {s['loop'].get('overruns', '?')} overruns; rig {lag}; {wall_s:.0f} s"
    )


def main(argv=None) -> int:
    a = parse(argv)
    held = sorted(a.out.glob("rig-*/meta.json")) if a.part != "sil" else []
    if held:
        print(f"error: {held[0].parent} already holds a log; choose another -o", file=sys.stderr)
        return 2
    if a.part in ("sil", "both"):
        sil_part(a)
    if a.part in ("rig", "both"):
        rig_part(a)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
