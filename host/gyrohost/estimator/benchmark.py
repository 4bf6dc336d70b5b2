"""Cost of one EKF cycle: predict 10 ms + fuse one IMU sample (rate, specific force, angles).

``python -m gyrohost.estimator.benchmark`` prints the median and the 90th percentile over a run
of cycles on the D-bar after the paper's manoeuvre has started, for the lean and the rk4 process
models, next to one evaluation of the reference right-hand side (:func:`gyrotensegrity.rhs`) as
the baseline measured in the same run.
"""

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from gyrotensegrity import Model, Stepper, load_scene, rhs

from .config import EstimatorConfig
from .ekf import TensegrityEKF
from .imu_model import euler_zyx
from .layout import from_model_state

DEFAULT_SCENE = Path(__file__).resolve().parents[3] / "scenes" / "dbar-gyro.toml"


def cycle_times(model, config, cycles=200, start_s=1.0):
    """Times of ``cycles`` EKF cycles, noise-free IMU samples of the scene run.

    Returns
    -------
    wall, cpu : ndarray, shape (cycles,), s
        Wall-clock and thread CPU time per cycle (the CPU time is what the cycle costs when
        other processes share the cores).
    """
    stepper = Stepper(model)
    stepper.step(start_s)
    u = model.input_at(stepper.t)
    x0 = from_model_state(model, stepper.x, u)
    ekf = TensegrityEKF(model, config, x0=x0, t0_s=stepper.t)
    R, _ = ekf.attitude()
    z_angle, z_rate, z_accel = euler_zyx(R[None])[0], np.zeros(3), np.array([0.0, 0.0, 9.8])
    wall, cpu = np.empty(cycles), np.empty(cycles)
    for k in range(cycles):
        t0, c0 = time.perf_counter(), time.thread_time()
        ekf.fuse_imu(ekf.t + config.process_dt_s, z_rate, z_accel, z_angle)
        wall[k], cpu[k] = time.perf_counter() - t0, time.thread_time() - c0
    return wall, cpu


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
    parser = argparse.ArgumentParser(prog="python -m gyrohost.estimator.benchmark")
    parser.add_argument("--scene", type=Path, default=DEFAULT_SCENE)
    parser.add_argument("--cycles", type=int, default=200)
    args = parser.parse_args(argv)
    model = Model(load_scene(args.scene))
    base = rhs_time(model)
    print(f"{args.scene.name}: reference rhs evaluation {base * 1e6:.0f} us (baseline)")
    for method in ("lean", "rk4"):
        cfg = replace(EstimatorConfig(), process_method=method)
        n = args.cycles if method == "lean" else max(args.cycles // 20, 5)
        wall, cpu = cycle_times(model, cfg, n)
        print(
            f"EKF cycle ({method:4s}): CPU median {np.median(cpu) * 1e3:.3f} ms "
            f"(p90 {np.percentile(cpu, 90) * 1e3:.3f} ms), wall median "
            f"{np.median(wall) * 1e3:.3f} ms = {np.median(wall) / base:.1f} rhs evaluations"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
