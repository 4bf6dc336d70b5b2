"""``python -m studies.attitude_closed_loop``: three-axis attitude maneuvers of the D-bar, open
loop against closed loop (re-planned every 0.25 s), on a truth whose parameters are off by the
identification's reported 1-sigma (J3 +0.5 %, string stiffness +5 %, damping +14 %).

Three parts:

- ``sil`` (simulated clock): the truth is dbar-rig, the rig-fidelity D-bar (hinges, stators,
  the motors' reaction: a wheel's speed change turns the structure, as the planner's momentum
  balance says), with dbar-gyro's n2-n4 follower string as the planner's model assumes, its
  scheduled wheels torque-driven by an ideal speed loop (``sil.run_maneuver_sil``). The
  estimate is the truth plus white noise on the nodes (:data:`NOISE`). Strings and wheels, wheels
  only, strings only, over targets inside the D-bar's reachable set ``tan(yaw) = tan(roll) /
  sin(pitch)`` (strings alone: turns about the momentum, the pitch axis). :data:`NOISE`
  gives the stand-in estimate the EKF's accuracy.
- ``prism`` (simulated clock): the stiff prism of studies.attitude_open_loop (its bars meet
  only strings, so its wheels act gyroscopically), planned on the nominal and played on a truth
  off by the same 1-sigma: strings s7 and s8 alone to a turn about its momentum, and with its
  three wheels (and its wheels alone: refused) to a target off the momentum, through the same
  Maneuver and planner classes as the D-bar (no prism code), estimate the truth plus
  :data:`NOISE`.
- ``rig`` (real time, EKF in the loop): ``gyrotens run --sim --target-attitude`` on the
  simulated rig (sim-rig) whose truth is the sil part's (dbar-rig with the follower string s24,
  off by the same 1-sigma), its wheels torque-driven by an ideal speed loop following the wheel
  board's true speeds (simrig/truth.py), so every speed change turns the structure by its
  reaction; the rig-fidelity model in the compiled kernel (gyrotensegrity.fast_rig). Strings
  and wheels on the three-axis targets, strings only on a pitch target, open and closed loop
  (re-planned in a thread); then the first target on the truth with heavier wheels (J3 x 1.05,
  as the sil part's last case), where open loop misses. The EKF models the motors' reaction
  (``wheel_reaction = "body"``, set by the truth). Limits asserted from each run's log: the
  truth's wheel speeds and accelerations, its rest lengths and the servos' string lengths.

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
from gyrotensegrity import Model, load_scene, scene_from_dict
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
    p.add_argument("--part", choices=("sil", "prism", "rig", "both"), default="both")
    p.add_argument("--duration", type=float, default=4.0, help="landing time, s")
    p.add_argument("--cases", type=int, default=len(CASES), help="the first N sil cases")
    p.add_argument("--rig-cases", type=int, default=len(RIG_CASES), help="the first N rig cases")
    p.add_argument("-o", "--out", type=Path, default=Path("out/attitude-closed-loop"))
    return p.parse_args(argv)


def truth_data(name):
    return tomllib.loads(shipped("scene", name).read_text())


STRESS_J3 = 1.05
"""A heavier truth's wheels (x 1.05, ten times the 1-sigma) for one more case: what closed loop
corrects when the model is clearly wrong."""


def rig_truth_scene(**factors):
    """dbar-rig with the follower string, off by ``factors`` (default 1-sigma), its wheels'
    torques left to the SIL's or the simulated rig's speed loop."""
    data = truth_data("dbar-rig")
    for bar in data["bars"]:
        bar["wheel"].pop("torque")
    data["strings"].append(dict(data["strings"][0], name="s24", nodes=["n2", "n4"]))
    return scaled_scene(data, "dbar-rig with s24", **(ONE_SIGMA | factors))


def rig_truth(**factors):
    """:func:`rig_truth_scene` as a model."""
    return Model(rig_truth_scene(**factors))


def within_limits(run, limits) -> bool:
    """The played schedule, the truth's wheels and the rest lengths played, inside the limits."""
    ok = not run.schedule.problems(limits)
    # the ideal speed loop lands on a command at the limit to round-off (Schedule.problems')
    ok &= bool(np.max(np.abs(run.wheel_speed_rad_s)) <= limits.max_wheel_speed_rad_s * (1 + 1e-9))
    for name, column in zip(run.schedule.names, run.rest_length_m.T, strict=True):
        low, high = limits.range_of(name)
        ok &= bool(low <= column.min() and column.max() <= high)
    return ok


def replan_times_ms(records):
    times = np.array([r.plan_time_s for r in records[1:]]) * 1e3
    if not times.size:
        return "-"
    return f"{np.median(times):.0f}/{times.max():.0f}"


def sil_case(nominal, truth, mode, target_deg, closed, a, strings=None):
    limits = Limits()
    target = Target(attitude_rpy_rad=tuple(np.radians(target_deg)), duration_s=a.duration,
                    closed_loop=closed, mode=mode, strings=strings)  # fmt: skip
    maneuver = Maneuver(nominal, limits, target)
    run = run_maneuver_sil(truth, maneuver, max_dt_s=2e-3, noise=NOISE, fast=True)
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


PRISM_STRINGS = ("s7", "s8")
"""The prism's actuated strings (as studies.attitude_open_loop's)."""
PRISM_TURN_DEG = 1.5
"""The strings-only target: a turn about the prism's momentum (roll, pitch and yaw all move)."""
PRISM_DURATION_S = 6.0
"""The prism's landing time (its strings' travel is shorter than the D-bar's)."""


def prism_part(a):
    """The stiff prism of studies.attitude_open_loop in simulated time, the truth 1-sigma off:
    strings s7 and s8 alone to a turn about the momentum, and with the three wheels (and the
    wheels alone, which turn a prism of fixed shape by nothing: refused) to a target off the
    momentum, open and closed loop, planned with the same classes as the D-bar."""
    from studies.attitude_open_loop import PRISM_TARGET_DEG, momentum_turn_deg, stiff_prism_data

    nominal = Model(scene_from_dict(stiff_prism_data(), "prism-stiff.toml"))
    truth = Model(scaled_scene(stiff_prism_data(), "prism-stiff", **ONE_SIGMA))
    cases = [("strings", tuple(momentum_turn_deg(nominal, PRISM_TURN_DEG)))]
    cases += [("both", PRISM_TARGET_DEG), ("wheels", PRISM_TARGET_DEG)]
    prism = argparse.Namespace(**{**vars(a), "duration": PRISM_DURATION_S})
    print(f"prism: truth {truth.scene.source}, strings {', '.join(PRISM_STRINGS)}, landing "
          f"at {PRISM_DURATION_S:g} s")  # fmt: skip
    for mode, target_deg in cases:
        for closed in (False, True):
            try:
                case = (nominal, truth, mode, target_deg, closed, prism, PRISM_STRINGS)
                line, _, _ = sil_case(*case)
            except PlanError as exc:
                print(f"{mode:8s}{', '.join(f'{v:+.1f}' for v in target_deg):>22s}  {exc}")
                break
            print(line, flush=True)


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


RIG_CASES = [("both", t) for t in THREE_AXIS_DEG] + [("strings", PITCH_DEG[0])]
"""The real-time part's cases: strings and wheels on the three-axis targets, strings alone on a
pitch target."""


def rig_part(a):
    """Real time on the simulated rig, EKF in the loop, the rig-fidelity truth: the cases at
    1-sigma, then the first on a truth with heavier wheels."""
    a.out.mkdir(parents=True, exist_ok=True)
    scene = rig_truth_scene()
    config = rig_config(a, scene, "1sigma")
    print(truth_speed(scene, config), flush=True)
    rig_runs(a, scene, config, RIG_CASES[: a.rig_cases], "1sigma")
    if a.rig_cases:
        stressed = rig_truth_scene(wheel_inertia=STRESS_J3)
        config = rig_config(a, stressed, "heavier-wheels")
        rig_runs(a, stressed, config, RIG_CASES[:1], "heavier-wheels")


def rig_config(a, scene, label):
    """sim-rig with ``scene`` (written to ``--out``) as its truth."""
    from gyrohost.config import load_rig_config
    from gyrohost.ident.scenefile import scene_toml
    from gyrohost.simrig.config import with_truth_scene

    truth_path = a.out / f"truth-dbar-rig-s24-{label}.toml"
    truth_path.write_text(scene_toml(scene, f"{scene.name}, parameters {label}"))
    return with_truth_scene(load_rig_config(shipped("config", "sim-rig")), truth_path)


def rig_runs(a, scene, config, cases, label):
    """Each case open and closed loop on the real-time simulated rig ``config`` with the truth
    ``scene``, logged under ``--out`` by ``label``."""
    from gyrohost.estimator.config import for_rig
    from gyrohost.run import run_simulated
    from gyrohost.run.request import planned_maneuver
    from gyrohost.simrig.config import sim_config

    estimator = for_rig(config)
    limits = Limits.per_string(config.servos.servo)
    sim = sim_config(config)
    step_m = max(2.0 * math.pi * s.pulley_radius_m / 4096 for s in config.servos.servo)
    tolerances = (sim.truth.dt_s, sim.servos.hold_band_steps * step_m)
    print(
        f"rig (real time, EKF): truth {scene.source}, wheels torque-driven; re-planned in a "
        "thread; limits from the log: truth wheels, truth rest lengths, servo lengths"
    )
    print(
        f"{'mode':8s}{'target r, p, y (deg)':>22s}{'loop':>8s}{'err deg':>9s}{'wheel':>9s}"
        f"{'servo mm':>9s}{'re-plans':>10s}{'ms med/max':>11s}{'late':>5s}{'limits':>7s}  run"
    )
    for mode, target_deg in cases:
        for closed in (False, True):
            target = Target(attitude_rpy_rad=tuple(np.radians(target_deg)),
                            duration_s=a.duration, mode=mode)  # fmt: skip
            target = replace(target, closed_loop=closed, threaded=closed)
            name = "_".join(f"{v:+g}" for v in target_deg)
            out = a.out / f"rig-{label}-{mode}-{name}-{closed:d}"
            start = time.perf_counter()
            try:
                maneuver = planned_maneuver(config, target, estimator)  # as the run's
                result = run_simulated(config, maneuver, out)
            except PlanError as exc:
                print(f"{mode:8s}{', '.join(f'{v:+.1f}' for v in target_deg):>22s}  {exc}")
                continue
            wall_s = time.perf_counter() - start
            line = rig_line(mode, target_deg, closed, result, out, limits, tolerances, wall_s)
            print(line, flush=True)


def truth_speed(scene, config, steps=200):
    """The simulated rig's truth step (5 ms: RK4, the speed loop's torques, a wheel spin-up and a
    string pull) on the compiled kernel and on the reference path, measured here, one after the
    other: wall ms per step and their ratio."""
    from gyrohost.simrig.config import sim_config
    from gyrohost.simrig.truth import Truth
    from gyrotensegrity import Stepper

    wall = {}
    for fast in (True, False):
        truth = Truth(scene, sim_config(config).truth, config.servos.servo)
        truth.release()
        truth.stepper = Stepper(truth.model, max_dt=truth.stepper.max_dt, fast=fast)
        spins = np.array([1.0, -1.0, -1.0, 1.0]) * 75.0
        start = time.perf_counter()
        for k in range(steps):
            pulled = {1: truth.rest_length_m[0] - 1e-4, 2: truth.rest_length_m[1]}
            truth.step(pulled, spins * min(1.0, (k + 1) / 100))
        wall[fast] = (time.perf_counter() - start) / steps
    return (
        f"truth step ({steps} steps of {1e3 * truth.dt_s:g} ms): kernel {1e3 * wall[True]:.3f} ms, "
        f"reference {1e3 * wall[False]:.3f} ms wall per step, {wall[False] / wall[True]:.0f} times"
    )


ACCEL_WINDOW_S = 0.05
"""The truth's wheel accelerations are asserted over this much truth time, against the limit
times ``1 + dt / window`` (1.1 at the truth's 5 ms step): each truth step takes the board's
speeds at the rig's poll, which a late step (a loaded CPU) takes a step later in device time,
and the board ramps its setpoints at its ``ACCEL_RAD_S2``, the limit itself."""


def log_limits(folder, limits, dt_s, band_m):
    """Peak truth wheel speed (rad/s), servo travel (mm) and whether the log stays inside the
    limits: the truth's wheel speeds, its rest lengths and the servos' string lengths within
    each string's range throughout; the truth's wheel accelerations (over
    :data:`ACCEL_WINDOW_S`) while the schedule plays and settles (the spin-up and the safe
    state's ramp-down are the wheel board's own ramps); ``dt_s`` the truth's step, s. The
    lengths may pass a range by ``band_m``: a servo stops within its hold band of a goal at the
    range's end (the emulator's ``hold_band_steps``), as a real one within its count."""
    from gyrohost.run.log import read_stream

    truth, servos = read_stream(folder, "truth"), read_stream(folder, "servos")
    truth = truth[np.concatenate([[True], np.diff(truth["truth_t_s"]) > 0.0])]  # new states
    omega = np.column_stack([truth[f"omega_{i}_rad_s"] for i in range(4)])
    events = read_stream(folder, "events")
    played = events["t_s"][(events["kind"] == "phase") & (events["message"] == "schedule")]
    ended = events["t_s"][events["kind"] == "end"]
    t = truth["truth_t_s"]
    later = np.searchsorted(t, t + ACCEL_WINDOW_S)
    ends = later < len(t)
    start, end = np.flatnonzero(ends), later[ends]
    during = (truth["t_s"][start] >= played.min(initial=np.inf)) & (
        truth["t_s"][end] <= ended.min(initial=np.inf)
    )
    accel = np.abs(omega[end] - omega[start]) / (t[end] - t[start])[:, None]
    ok = bool(np.abs(omega).max() <= limits.max_wheel_speed_rad_s)
    slack = 1.0 + dt_s / ACCEL_WINDOW_S
    ok &= bool(accel[during].max(initial=0.0) <= slack * limits.max_wheel_accel_rad_s2)
    travel = 0.0
    for name in ("s13", "s24"):
        low, high = limits.range_of(name)
        for column in (truth[f"{name}_rest_m"], servos[f"{name}_length_m"]):
            ok &= bool(low - band_m <= column.min() and column.max() <= high + band_m)
        travel = max(travel, float(np.ptp(servos[f"{name}_length_m"])) * 1e3)
    return float(np.abs(omega).max()), travel, ok


def rig_line(mode, target_deg, closed, result, folder, limits, tolerances, wall_s):
    s = result.summary
    m = s["maneuver"]
    error = s.get("attitude_end_truth_error_rad", math.nan)
    times = (
        f"{1e3 * m['replan_time_median_s']:.0f}/{1e3 * m['replan_time_max_s']:.0f}"
        if m["replans"]
        else "-"
    )
    wheel, travel, ok = log_limits(folder, limits, *tolerances)
    lag = s.get("rig_real_time", {})
    plans = f"{m['replans']} ({m['replans_accepted']})"
    ekf = "diverged" if s["estimator"].get("diverged") else "ok"
    return (
        f"{mode:8s}{', '.join(f'{v:+.1f}' for v in target_deg):>22s}"
        f"{'closed' if closed else 'open':>8s}{math.degrees(error):>9.3f}{wheel:>9.1f}"
        f"{travel:>9.1f}{plans:>10s}{times:>11s}{m.get('replans_late', 0):>5d}"
        f"{'yes' if ok else 'NO':>7s}  {s['reason']}; EKF {ekf}, NEES "
        f"{s['estimator'].get('nees', {}).get('mean', math.nan):.1f}; truth late "
        f"{lag.get('late_share', math.nan):.1%}, max lag {1e3 * lag.get('max_lag_s', math.nan):.0f}"
        f" ms; loop {s['loop'].get('overruns', '?')} overruns; {wall_s:.0f} s"
    )


def main(argv=None) -> int:
    a = parse(argv)
    held = sorted(a.out.glob("rig-*/meta.json")) if a.part in ("rig", "both") else []
    if held:
        print(f"error: {held[0].parent} already holds a log; choose another -o", file=sys.stderr)
        return 2
    if a.part in ("sil", "both"):
        sil_part(a)
    if a.part in ("prism", "both"):
        prism_part(a)
    if a.part in ("rig", "both"):
        rig_part(a)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
