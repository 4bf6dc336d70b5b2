"""A shipped schedule on the acceptance truth, recorded and identified on the simulated clock.

``python -m studies.identify_preset [--schedule identify] [--seeds 5]
[--first-seed 1] [--segment-s 4] [--lengths command] [--out DIR]``

The rig of :mod:`.identify_rig` (the host's configuration ``sim-rig`` with the bars weighed; the
truth the shipped D-bar with J3 x 1.3, bar mass x 0.8, string stiffness x 1.25, damping x 0.7,
its IMU turned (3, -1.7, 1.1) degrees) plays the schedule in full on the rig's models in process
(:func:`.estimator_sil.rig_model_run`: truth, servos with their 50 ms lag, IMU and wheel-board
emulators; seed = IMU noise and biases, wheel angles), instead of the real-time rig, after the
run's 0.5 s lead-in (:func:`with_lead_in`: the log's time is the schedule's plus 0.5 s, as in
a run's log). The log is fitted as ``gyrotens identify --segment-s S`` fits it (the default
groups; string lengths from the commands through the servos' lag, or the servos' reports with
``--lengths servos``).

Per seed: the errors against the truth and their reported 1-sigmas
(:func:`.identify_check.errors`), the segments left out, the fit's CPU time, when the truth's
sensor has turned 60 degrees from its start, and per segment the linearised 1-sigma of
log-stiffness and log-damping that its data alone would give (all parameters free), the same
over the segments up to it, and how well the truth's own J3, stiffness and damping predict it
(:func:`segment_figures`).
"""

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROLLED_RAD = np.radians(60.0)
"""How far the truth's sensor turns from where it started before it counts as rolled over, rad
(the nominal truth tilts by 0.24 rad on the identify schedule, docs/schedule.md)."""
INFORMED = ("stiffness", "damping")


def record(folder: Path, schedule_name: str, seed: int) -> tuple[Path, Path, float]:
    """Record one run of the schedule on the acceptance truth in ``folder``.

    Returns
    -------
    config : Path
        The host's configuration (bars weighed).
    log : Path
    rolled_s : float
        When the truth's sensor had turned :data:`ROLLED_RAD` from its start, s (``nan``: never).
    """
    from gyrohost.config import load_rig_config
    from gyrohost.geometry import turn_from_first
    from gyrohost.ident.simcheck import write_log
    from gyrohost.run.request import load_schedule_arg
    from gyrohost.sil.scoring import rig_model_run
    from gyrohost.simrig.config import with_truth_scene
    from studies.identify_rig import write_rig_files

    config_path, truth_path = write_rig_files(folder, seed)
    config = with_truth_scene(load_rig_config(config_path), truth_path)
    schedule = with_lead_in(load_schedule_arg(schedule_name, config.scene_path))
    _, data, _, truth_R, _, dt_s = rig_model_run(config, seed, schedule.t_end, schedule=schedule)
    over = np.flatnonzero(turn_from_first(truth_R) > ROLLED_RAD)
    rolled_s = float(over[0] * dt_s) if len(over) else float("nan")
    return config_path, write_log(data, folder / "log"), rolled_s


def with_lead_in(schedule):
    """``schedule`` held at its first sample for the run's ``lead_in`` first
    (:class:`gyrohost.run.settings.RunSettings`), as a run plays it: the log's time (the fit's)
    is the schedule's plus the lead-in."""
    from gyrohost.control.schedule import Schedule
    from gyrohost.run.settings import RunSettings

    lead_s = RunSettings().lead_in_s
    return Schedule(
        schedule.names,
        np.append(0.0, schedule.t + lead_s),
        np.vstack([schedule.rest_length[:1], schedule.rest_length]),
        schedule.name,
        schedule.wheels,
        np.vstack([schedule.wheel_speed[:1], schedule.wheel_speed]),
    )


def segment_figures(result, scene, config, est, recs) -> list[tuple]:
    """Per segment of the (one) recording, every segment kept and started from the IMU read with
    the fit's mounting and gyro bias: the linearised 1-sigma of the :data:`INFORMED` parameters
    at the fit's optimum (the Jacobian of the weighted residuals by central differences at the
    parameters' steps; ``(J_s^T J_s)^+`` over the segment's rows alone and over the rows up to
    its end), and the weighted residual RMS with the truth's J3, stiffness and damping (the
    fit's mounting and biases): about 1 where the prediction follows the recording.

    Returns
    -------
    list of (start, end, own, cumulative, rms_truth)
        Times in s; ``own`` and ``cumulative`` map parameter name -> 1-sigma (log factor).
    """
    from gyrohost.ident import forward, shooting
    from gyrohost.ident.fit import Problem, anchored
    from gyrohost.ident.params import apply
    from gyrohost.ident.simcheck import FACTORS

    theta = result.theta
    (rec,) = anchored(recs, apply(scene, config, result.params, theta, result.servo_lag_s))
    problem = Problem(scene, config, est, result.params, [rec])
    columns = []
    for i, p in enumerate(result.params):
        e = np.zeros(len(theta))
        e[i] = p.step
        columns.append((problem(theta + e) - problem(theta - e)) / (2.0 * p.step))
    J = np.column_stack(columns).reshape(len(rec.t_imu_s), -1, len(theta))
    names = [p.name for p in result.params]
    true = theta.copy()
    for name in ("J3", "stiffness", "damping"):
        true[names.index(name)] = np.log(FACTORS[name])
    r_true = problem(true).reshape(len(rec.t_imu_s), -1)
    edges = shooting.edges_s(rec, forward.STEP_S)
    edges[-1] = rec.t_imu_s[-1]
    idx = [names.index(n) for n in INFORMED]
    out = []
    for t0, t1 in zip(edges[:-1], edges[1:], strict=True):
        own = (rec.t_imu_s >= t0) & (rec.t_imu_s <= t1)
        upto = rec.t_imu_s <= t1
        rms = float(np.sqrt(np.mean(r_true[own] ** 2)))
        sigmas = _sigmas(J[own], idx, names), _sigmas(J[upto], idx, names)
        out.append((float(t0), float(t1), *sigmas, rms))
    return out


def _sigmas(J, idx, names) -> dict:
    J = J.reshape(-1, J.shape[-1])
    cov = np.linalg.pinv(J.T @ J)
    return {names[i]: float(np.sqrt(max(cov[i, i], 0.0))) for i in idx}


def one_seed(root: Path, schedule: str, seed: int, segment_s: float, commanded: bool) -> dict:
    """Record and identify one seed; the figures of the module docstring."""
    from gyrohost.ident.fit import fit
    from gyrohost.ident.groups import DEFAULT_GROUPS
    from gyrohost.ident.simcheck import errors, fit_inputs

    folder = root / f"seed{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    config, log, rolled_s = record(folder, schedule, seed)
    inputs = fit_inputs(config, [log], DEFAULT_GROUPS, segment_s, commanded)
    cpu0 = time.process_time()
    result = fit(*inputs)
    cpu_s = time.process_time() - cpu0
    return {
        "errors": errors(result, weighed=True),
        "dropped": [(t0, t1) for _, t0, t1 in result.dropped],
        "rolled_s": rolled_s,
        "fit_cpu_s": cpu_s,
        "segments": segment_figures(result, *inputs[:3], inputs[4]),
    }


def _print(seed: int, out: dict) -> None:
    e = out["errors"]
    rel = "  ".join(
        f"{k} {100 * np.expm1(e[k][0]):+.1f} % (sigma {100 * e[k][1]:.1f} %)"
        for k in ("J3", "stiffness", "damping")
        if k in e
    )
    mount = " / ".join(
        f"{np.degrees(e[f'mounting.{a}'][0]):+.3f}" for a in ("roll", "pitch", "yaw")
    )
    dropped = ", ".join(f"{a:.1f}-{b:.1f}" for a, b in out["dropped"]) or "none"
    turned, cpu = out["rolled_s"], out["fit_cpu_s"]
    print(f"seed {seed}: {rel}  mounting {mount} deg  left out {dropped} s  "
          f"turned 60 deg at {turned:.2f} s  fit {cpu:.0f} s CPU")  # fmt: skip
    for t0, t1, own, upto, rms in out["segments"]:
        kept = not any(a <= t0 < b for a, b in out["dropped"])
        line = "  ".join(f"{k} {100 * own[k]:6.1f} % / {100 * upto[k]:6.1f} %" for k in INFORMED)
        print(f"  segment {t0:5.1f}-{t1:5.1f} s{'' if kept else ' (left out)'}: "
              f"1-sigma own / up to its end: {line}; RMS at the truth {rms:.2f}",
              flush=True)  # fmt: skip


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m studies.identify_preset")
    parser.add_argument("--schedule", default="identify", help="schedule file or shipped name")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--first-seed", type=int, default=1)
    parser.add_argument("--segment-s", type=float, default=4.0, help="segments, s (4; 0: one)")
    parser.add_argument("--lengths", choices=("command", "servos"), default="command")
    parser.add_argument("--out", type=Path, help="keep the logs here (default: temporary)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        root = args.out or Path(tmp)
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            out = one_seed(root, args.schedule, seed, args.segment_s, args.lengths == "command")
            _print(seed, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
