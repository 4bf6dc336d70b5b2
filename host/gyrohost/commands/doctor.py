"""``gyrotens doctor --config FILE``: one PASS/FAIL line per check of a rig configuration and its
devices; the exit status is the number of failures. Nothing moves (docs/bring-up.md)."""

from gyrohost.bringup import add_hello_timeout


def register(sub) -> None:
    p = sub.add_parser("doctor", help="check a rig configuration and its devices (nothing moves)")
    p.add_argument("--config", required=True, help="rig configuration: a TOML file or shipped name")
    p.add_argument(
        "--imu-window", type=float, default=1.0, metavar="S", help="IMU rate measured over (1 s)"
    )
    add_hello_timeout(p)
    p.add_argument(
        "--imu-rate-tolerance",
        type=float,
        default=0.2,
        metavar="F",
        help="measured IMU rate within this fraction of imu.rate_hz (0.2)",
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from gyrohost.bringup.doctor import Check, Windows, run_checks
    from gyrohost.config import load_rig_config
    from gyrohost.errors import GyrohostError
    from gyrohost.resources import resolve

    try:
        config = load_rig_config(resolve("config", args.config))
    except GyrohostError as exc:
        print(Check("configuration", False, str(exc)).line())
        return 1
    print(Check("configuration", True, config.source).line())
    failures = 0
    for check in run_checks(
        config, windows=Windows(args.imu_window, args.hello_timeout, args.imu_rate_tolerance)
    ):
        print(check.line(), flush=True)
        failures += not check.ok
    return failures
