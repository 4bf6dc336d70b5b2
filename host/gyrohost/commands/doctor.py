"""``gyrotens doctor --config FILE``: one PASS/WARN/FAIL line per check of a rig configuration and
its devices; exit status 0 when nothing FAILs, 1 when something does, 2 for a configuration that
cannot be read. Nothing turns (docs/bring-up.md)."""

from gyrohost.bringup import add_hello_timeout


def register(sub) -> None:
    p = sub.add_parser(
        "doctor",
        help="check a rig configuration and its devices: PASS, WARN or FAIL per line "
        "(exit 1 on a FAIL)",
    )
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
    from gyrohost.bringup.devices import load_config
    from gyrohost.bringup.doctor import PASS, Check, Windows, run_checks
    from gyrohost.commands.errors import CliError
    from gyrohost.errors import GyrohostError

    try:
        config = load_config(args.config)
    except GyrohostError as exc:
        raise CliError(str(exc)) from None
    print(Check("configuration", PASS, config.source).line())
    failed = False
    windows = Windows(args.imu_window, args.hello_timeout, args.imu_rate_tolerance)
    for check in run_checks(config, windows=windows):
        print(check.line(), flush=True)
        failed |= not check.ok
    return int(failed)
