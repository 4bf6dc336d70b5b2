"""The EKF's consistency on synthetic runs: a Monte Carlo of the paper's D-bar manoeuvre.

``python -m studies.estimator_montecarlo [--runs 20] [--duration 3] [--method lean|rk4|both]
[--serial | --scheduler ADDRESS | --workers N]``: :func:`gyrohost.sil.montecarlo.run_monte_carlo`
per process model, its averages against the 95 % chi-square bounds of an N-run average.
"""

import argparse
from dataclasses import replace
from pathlib import Path

from gyrohost import parallel
from gyrohost.estimator.config import EstimatorConfig
from gyrohost.sil.montecarlo import DEFAULT_SCENE, run_monte_carlo, summarise
from gyrotensegrity import Model, load_scene


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m studies.estimator_montecarlo")
    parser.add_argument("--scene", type=Path, default=DEFAULT_SCENE)
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--duration", type=float, default=3.0, help="s")
    parser.add_argument("--method", choices=("lean", "rk4", "both"), default="both")
    parallel.add_arguments(parser)
    args = parser.parse_args(argv)
    model = Model(load_scene(args.scene))
    methods = ("lean", "rk4") if args.method == "both" else (args.method,)
    with parallel.from_args(args) as executor:
        for method in methods:
            cfg = replace(EstimatorConfig(), process_method=method)
            print(f"--- {args.runs} runs of {args.duration} s, process model {method}")
            results = run_monte_carlo(model, cfg, args.runs, args.duration, executor=executor)
            summarise(results, f"[{method}] ")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
