"""``gyrotens sweep SPEC.toml -o DIR``: a scene's parameters swept, every case a Dask task.

``SPEC`` is a sweep spec (docs/sweeps.md) or the name of a shipped one (``dbar-turn``). The cases
run on a Dask ``LocalCluster`` of this machine's cores, on a running scheduler with
``--scheduler tcp://host:8786``, or one after the other with ``--serial``; finished cases are
kept in DIR and not run again.
"""

import sys
import time
from functools import partial
from pathlib import Path

from gyrohost import parallel


def register(sub) -> None:
    p = sub.add_parser("sweep", help="sweep a scene's parameters (Dask), table and plots")
    p.add_argument("spec", help="sweep spec (TOML, docs/sweeps.md) or shipped name (dbar-turn)")
    p.add_argument("-o", "--out", type=Path, required=True, help="results directory")
    p.add_argument(
        "--max-cases",
        type=int,
        metavar="N",
        help="refuse a sweep of more cases than N (default 10000)",
    )
    p.add_argument("--yes", action="store_true", help="run however many cases the spec has")
    parallel.add_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from gyrohost.commands.errors import CliError, executor_status
    from gyrohost.parallel import ExecutorError
    from gyrohost.sweep import SpecError, load_spec, run_sweep
    from gyrohost.sweep.plots import goal_score
    from gyrohost.sweep.run import MAX_CASES, check_size

    try:
        import pyarrow  # noqa: F401  (the table; checked before any case runs)
    except ImportError as exc:
        raise CliError(f"{exc}: pip install 'gyrotensegrity[sweep]'") from None
    limit = None if args.yes else (MAX_CASES if args.max_cases is None else args.max_cases)
    try:
        spec = load_spec(args.spec)
        n = check_size(spec, limit)
        executor = parallel.from_args(args, progress=True)
    except (SpecError, ExecutorError) as exc:
        raise CliError(str(exc)) from None
    print(f"{spec.name}: {spec.scene_path.name}, {len(spec.axes)} axes, {n} cases, "
          f"{executor.describe()}", flush=True)  # fmt: skip
    start = time.perf_counter()
    try:
        with executor:
            ready = time.perf_counter()
            estimate = partial(_estimate, slots=executor.slots())
            result = run_sweep(spec, args.out, executor, on_first=estimate)
    except ExecutorError as exc:
        return executor_status("sweep", exc)
    wall_s = time.perf_counter() - ready
    print(
        f"\n{len(result.rows)} cases: {result.ran} run, {result.kept} kept from {args.out}, "
        f"{result.failed} failed; {wall_s:.1f} s ({result.ran / wall_s:.2f} cases/s) after "
        f"{ready - start:.1f} s to start the executor"
    )
    for row in [r for r in result.rows if r["error"] is not None][:3]:
        print(f"  case {row['case']} failed: {row['error']}")
    if spec.pareto and "target" in spec.pareto:
        ok = [r for r in result.rows if r["error"] is None]
        names = [a.name for a in spec.axes] + [spec.pareto["goal"]]
        for k in goal_score(spec, ok).argsort()[:5]:
            print("  closest to target: " + ", ".join(f"{n} {ok[k][n]:.4g}" for n in names))
    for path in result.files:
        print(f"wrote {path}", file=sys.stderr)
    return 1 if result.failed else 0


def _estimate(pending: int, first_s: float, slots: int) -> None:
    """Say how long the sweep's cases will take, from the first one's time."""
    rest_s = first_s * (pending - 1) / slots
    print(
        f"{pending} cases to run; the first took {first_s:.2f} s: about {rest_s:.0f} s more "
        f"for the rest, {slots} at a time",
        flush=True,
    )
