"""``gyrotens bench [--quick] [-o DIR]``: speed against accuracy, peers, scaling, extremes.

Writes DIR/report.md, DIR/bench.json and the plots. ``--quick`` is the smoke version (small grids,
short runs; under 2 minutes on 2 cores); the full run is what reports/model-performance.md carries
(its headline figures in docs/performance.md). Everything runs serially in this process (timings
must not share cores) unless ``--workers N`` or ``--scheduler ADDRESS`` sends the extremes' cells to
Dask (docs/sweeps.md).
"""

import sys
import time
from pathlib import Path

from gyrohost import parallel


def register(sub) -> None:
    p = sub.add_parser("bench", help="benchmark: speed/accuracy trade, MuJoCo, scaling, extremes")
    p.add_argument("--quick", action="store_true", help="smoke version (< 2 minutes)")
    p.add_argument("-o", "--out", type=Path, default=Path("out/bench"), help="report directory")
    p.add_argument(
        "--skip",
        action="append",
        default=[],
        choices=["trade", "peers", "scaling", "extremes"],
        help="leave a section out (repeatable)",
    )
    parallel.add_arguments(p, serial_default=True)  # timing: serial unless asked
    p.set_defaults(func=run)


def _log(msg):
    print(msg, flush=True)


def run(args) -> int:
    from gyrohost.bench import extremes, peers, report, timing, trade
    from gyrohost.commands.errors import executor_status
    from gyrotensegrity.fast import FastDynamics

    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    data = {"quick": args.quick, "machine": report.machine()}
    dbar = trade.dbar_model()
    data["kernel"] = FastDynamics(dbar).kernel is not None
    _log("D-bar right-hand side")
    data["dbar_rhs"] = timing.rhs_costs(
        dbar,
        dbar.initial_state(),
        dbar.input_at(1.0),
        repeats=3 if args.quick else 7,
        target_s=0.02 if args.quick else 0.1,
    )
    d = data["dbar_rhs"]
    _log(f"  reference {d['reference'] * 1e6:.1f} us, fast {d['fast'] * 1e6:.2f} us")
    data["ekf"] = timing.ekf_budget(
        dbar, repeats=3 if args.quick else 7, target_s=0.02 if args.quick else 0.1
    )
    data["trade"], data["recommend"] = [], []
    if "trade" not in args.skip:
        _log("speed against accuracy")
        for case in trade.cases(args.quick):
            _log(f" {case.name}")
            data["trade"] += trade.run_case(case, args.quick, _log)
        data["recommend"] = trade.recommend(data["trade"])
    data["peers"] = {
        "duration_s": 0,
        "ours": [],
        "mujoco": [],
        "mujoco_available": False,
        "matlab_ms_per_step": peers.MATLAB_MS_PER_STEP,
    }
    if "peers" not in args.skip:
        _log("peers (MuJoCo)")
        data["peers"] = peers.compare(args.quick, _log)
    if "scaling" not in args.skip:
        _log("scaling")
        data["scaling"] = timing.scaling(args.quick, _log)
        data["exponents"] = {
            "class-1": timing.fit_exponent(data["scaling"], "fast", False),
            "class-2": timing.fit_exponent(data["scaling"], "fast", True),
        }
    if "extremes" not in args.skip:
        _log("extremes")
        try:
            with parallel.from_args(args) as executor:
                data["extremes"] = extremes.sweep(args.quick, _log, executor)
        except parallel.ExecutorError as exc:
            return executor_status("bench", exc)
    data["bench_wall_s"] = time.perf_counter() - start
    files = report.plots(out, data)
    report.write_json(out / "bench.json", data)
    (out / "report.md").write_text(report.markdown(data, files))
    print(f"wrote {out / 'report.md'} ({data['bench_wall_s']:.0f} s)", file=sys.stderr)
    return 0
