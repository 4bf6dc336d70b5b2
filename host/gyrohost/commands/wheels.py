"""``gyrotens wheels calibrate PORT``: find each wheel's electrical zero with its motor, save it."""

import sys


def register(sub) -> None:
    p = sub.add_parser("wheels", help="wheel-board set-up (calibrate the encoder offsets)")
    actions = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    c = actions.add_parser(
        "calibrate",
        help="CALIBRATE_ENC on each wheel (it turns back and forth by one electrical turn), "
        "then PARAM_SAVE",
    )
    c.add_argument("port", help="the wheel board's serial port, e.g. /dev/ttyACM0")
    c.add_argument(
        "--wheel", type=int, action="append", choices=range(4), help="wheel 0..3 (default: all)"
    )
    c.add_argument("--no-save", action="store_true", help="keep the offsets in RAM only")
    c.set_defaults(func=calibrate)


def calibrate(args) -> int:
    from gyrohost.bringup.wheel_faults import clear_reported_faults
    from gyrohost.drivers.errors import WheelBoardError
    from gyrohost.drivers.wheelboard import WheelBoard

    wheels = sorted(set(args.wheel or range(4)))
    try:
        with WheelBoard(args.port) as board:
            clear_reported_faults(board, lambda line: print(line, file=sys.stderr))
            for w in wheels:
                offset = board.calibrate(w, save=False)
                print(f"wheel {w}: ENC_OFFSET_M{w} = {offset} ({offset * 360 / 65536:.1f} deg)")
            if not args.no_save:
                board.save_params()
                print("saved to EEPROM")
    except (WheelBoardError, OSError) as exc:  # CalibrationError names the wheel and reason
        print(f"gyrotens wheels: {exc}", file=sys.stderr)
        return 1
    return 0
