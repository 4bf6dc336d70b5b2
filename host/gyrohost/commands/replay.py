"""``gyrotens replay LOG [-o OUT]``: rerun the estimator over a run log (deterministic)."""

from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("replay", help="rerun the estimator over a run log, write a new log")
    p.add_argument("log", type=Path, help="log folder (meta.json + CSV streams)")
    p.add_argument("-o", "--out", type=Path, help="output log folder (default: LOG-replay)")
    p.add_argument("--scene", type=Path, help="scene file (default: 'scene' in meta.json)")
    p.add_argument("--config", type=Path, help="TOML with an [estimator] table")
    p.set_defaults(func=run)


def run(args) -> int:
    from gyrohost.cli import CliError
    from gyrohost.estimator import EstimatorConfigError, EstimatorError, load_config
    from gyrohost.run.log import LogError
    from gyrohost.run.replay import replay
    from gyrotensegrity import SceneError

    out = args.out or args.log.with_name(args.log.name + "-replay")
    try:
        config = load_config(args.config) if args.config else None
        summary = replay(args.log, out, scene=args.scene, config=config)
    except (LogError, EstimatorConfigError, EstimatorError, SceneError, FileExistsError) as exc:
        raise CliError(str(exc)) from None
    for source, c in summary["sources"].items():
        print(
            f"{source:10s} accepted {c['accepted']:6d}  rejected {c['rejected']:5d}  "
            f"stale {c['stale']:4d}  time-outs {c['timeouts']:3d}"
        )
    print(f"final status 0x{summary['final_status']:04x}; wrote {out}")
    return 0
