"""``gyrotens doctor --config FILE``: one PASS/FAIL line per check of a rig configuration and its
devices; the exit status is the number of failures. Nothing moves (docs/bring-up.md)."""


def register(sub) -> None:
    p = sub.add_parser("doctor", help="check a rig configuration and its devices (nothing moves)")
    p.add_argument("--config", required=True, help="rig configuration: a TOML file or shipped name")
    p.add_argument(
        "--imu-window", type=float, default=1.0, metavar="S", help="IMU rate measured over (1 s)"
    )
    p.add_argument(
        "--hello-timeout",
        type=float,
        default=2.5,
        metavar="S",
        help="wait for the wheel board's HELLO reply (its bootloader runs first; 2.5 s)",
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
    for check in run_checks(config, windows=Windows(args.imu_window, args.hello_timeout)):
        print(check.line(), flush=True)
        failures += not check.ok
    return failures
