"""Cost of one EKF cycle: predict 10 ms + fuse one IMU sample (rate, specific force, angles).

``python -m studies.estimator_benchmark`` prints the median and the 90th percentile
over a run of cycles on the D-bar during the paper's manoeuvre (IMU samples of the reference
model), for the lean and the rk4 process models, each with the dynamics' Jacobian by the
complex step and in closed form (``--jacobian``, default both), with the rest-length jitter
through the strings' kinks (``--rest-jitter-psd``, default the SIL's 2e-10 m^2 s; 0 leaves it
out), next to one evaluation of the reference right-hand side (:func:`gyrotensegrity.rhs`) as
the baseline measured in the same run. The filters time the reference path (``fast=False``);
the lean model with the closed-form Jacobian runs a second time on the fast path (an IMU
sample's step and fusion in one kernel call, :mod:`gyrohost.estimator.fast_cycle`), beside the
reference, and their ratio is printed. The filters take turns in blocks of :data:`BLOCK`
cycles: a change of the machine's load during the run falls on all of them alike, as it would
cycle by cycle, but each block runs with its own data in the caches, as a filter does on the
rig, where it runs alone. The lean model runs with either string kink (``--kink-model``,
default both: ``sharp``, and ``mean``, the simulated rigs')."""

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from gyrohost.estimator.config import EstimatorConfig
from gyrohost.estimator.ekf import TensegrityEKF
from gyrohost.estimator.imu_model import euler_zyx
from gyrohost.resources import shipped
from gyrohost.sil.synthetic import simulate_truth
from gyrotensegrity import Model, load_scene, rhs

DEFAULT_SCENE = shipped("scene", "dbar-gyro")
JACOBIANS = ("complex-step", "analytic")
KINKS = ("sharp", "mean")
BLOCK = 20
"""Cycles a filter runs before the next takes its turn (:func:`cycle_times`)."""


def cycle_times(model, variants, cycles=200, start_s=0.5):
    """Times of ``cycles`` EKF cycles on noise-free IMU samples of the scene's manoeuvre, one
    filter per variant ``(config, fast)`` (:class:`TensegrityEKF`'s arguments), taking turns in
    blocks of :data:`BLOCK` cycles.

    Returns
    -------
    wall, cpu : ndarray, shape (len(variants), cycles), s
        Wall-clock and thread CPU time per cycle (the CPU time is what the cycle costs when
        other processes share the cores).
    accepted : ndarray, shape (len(variants),)
        Share of the IMU measurements the gates let through (the cycles timed did fuse).
    """
    configs = [config for config, _ in variants]
    truth = simulate_truth(
        model, configs[0], start_s + cycles * 0.01, seed=0, dt_s=0.01, accel_psd_m2_s3=0.0
    )
    k0 = int(round(start_s / 0.01))
    ekfs = [
        TensegrityEKF(model, c, x0=truth.x[k0], t0_s=truth.t_s[k0], fast=fast)
        for c, fast in variants
    ]
    logs = [[] for _ in configs]
    for ekf, log in zip(ekfs, logs, strict=True):
        ekf.log = log.append
    angles = euler_zyx(truth.R_ws)
    rate = truth.omega_s + truth.x[:, ekfs[0].layout.bias]
    wall, cpu = np.empty((len(configs), cycles)), np.empty((len(configs), cycles))
    for start in range(0, cycles, BLOCK):
        for i, ekf in enumerate(ekfs):
            for j in range(start, min(start + BLOCK, cycles)):
                k = k0 + 1 + j
                ekf.set_input(truth.command[k - 1], truth.t_s[k - 1])
                t0, c0 = time.perf_counter(), time.thread_time()
                ekf.fuse_imu(truth.t_s[k], rate[k], truth.specific_force[k], angles[k])
                wall[i, j], cpu[i, j] = time.perf_counter() - t0, time.thread_time() - c0
    return wall, cpu, np.array([np.mean([r.accepted for r in log]) for log in logs])


def rhs_time(model, repeats=200):
    """Median wall time of one reference right-hand-side evaluation, s."""
    x, u = model.initial_state(), model.input_at(0.0)
    times = np.empty(repeats)
    for k in range(repeats):
        t0 = time.perf_counter()
        rhs(0.0, x, u, model)
        times[k] = time.perf_counter() - t0
    return float(np.median(times))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m studies.estimator_benchmark")
    parser.add_argument("--scene", type=Path, default=DEFAULT_SCENE)
    parser.add_argument("--cycles", type=int, default=200)
    parser.add_argument(
        "--rest-jitter-psd",
        type=float,
        default=2e-10,
        help="rest_jitter_psd_m2_s, m^2 s (default: the SIL's; 0 leaves the kink noise out)",
    )
    parser.add_argument(
        "--jacobian",
        choices=JACOBIANS,
        action="append",
        help="the estimator's jacobian key (repeat for several; default: both)",
    )
    parser.add_argument(
        "--kink-model",
        choices=KINKS,
        action="append",
        help="the lean model's kink_model (repeat for both; default: both)",
    )
    parser.add_argument(
        "--wheel-noise-ma1",
        type=float,
        default=0.0,
        help="wheel_noise_ma1 (nonzero: the wheel noise states, 4 more on the D-bar)",
    )
    args = parser.parse_args(argv)
    model = Model(load_scene(args.scene))
    base = rhs_time(model)
    print(f"{args.scene.name}: reference rhs evaluation {base * 1e6:.0f} us (baseline)")
    runs = [("lean", kink) for kink in args.kink_model or KINKS] + [("rk4", "sharp")]
    for method, kink in runs:
        jacobians = args.jacobian or JACOBIANS
        configs = [
            replace(
                EstimatorConfig(),
                process_method=method,
                jacobian=jacobian,
                rest_jitter_psd_m2_s=args.rest_jitter_psd,
                wheel_noise_ma1=args.wheel_noise_ma1,
                kink_model=kink,
            )
            for jacobian in jacobians
        ]
        variants = [(c, False) for c in configs]
        labels = list(jacobians)
        if method == "lean" and "analytic" in jacobians:
            variants.append((configs[jacobians.index("analytic")], True))
            labels.append("analytic,fast")
        n = args.cycles if method == "lean" else max(args.cycles // 20, 5)
        wall, cpu, accepted = cycle_times(model, variants, n)
        for i, label in enumerate(labels):
            print(
                f"EKF cycle ({method:4s}, {kink:5s}, {label:13s}): CPU median "
                f"{np.median(cpu[i]) * 1e3:.3f} ms (p90 {np.percentile(cpu[i], 90) * 1e3:.3f} "
                f"ms), wall median {np.median(wall[i]) * 1e3:.3f} ms = "
                f"{np.median(wall[i]) / base:.1f} rhs evaluations; "
                f"{100 * accepted[i]:.0f} % of the IMU measurements fused"
            )
        if len(jacobians) > 1:
            ratios = np.median(cpu[1 : len(jacobians)] / cpu[0], axis=1)
            pairs = ", ".join(f"{j} {r:.2f}" for j, r in zip(jacobians[1:], ratios, strict=True))
            print(f"  CPU per cycle against {jacobians[0]} (median of the cycles' ratios): {pairs}")
        if labels[-1] == "analytic,fast":
            ratio = np.median(cpu[-1] / cpu[jacobians.index("analytic")])
            print(
                f"  fast path against the reference (lean, analytic), median of the cycles' CPU "
                f"ratios: {ratio:.3f} ({1 / ratio:.1f} times faster)"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
