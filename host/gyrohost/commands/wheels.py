"""``gyrotens wheels calibrate|spin``: each wheel's electrical zero found and saved; one wheel
spun slowly for a few seconds and ramped down (docs/bring-up.md)."""

import sys

from gyrohost.bringup import add_hello_timeout
from gyrohost.commands.devices import add_device_options, say


def register(sub) -> None:
    p = sub.add_parser("wheels", help="the wheel board: calibrate the offsets, spin one wheel")
    actions = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    c = actions.add_parser(
        "calibrate",
        help="CALIBRATE_ENC on each wheel (it turns back and forth by one electrical turn), "
        "then PARAM_SAVE",
    )
    c.add_argument("old_port", nargs="?", metavar="PORT", help="deprecated: use --port")
    add_device_options(c, "wheel board")
    add_hello_timeout(c)
    c.add_argument(
        "--wheel", type=int, action="append", choices=range(4), help="wheel 0..3 (default: all)"
    )
    c.add_argument("--no-save", action="store_true", help="keep the offsets in RAM only")
    c.set_defaults(func=calibrate)
    s = actions.add_parser("spin", help="spin one wheel slowly, then ramp it down")
    add_device_options(s, "wheel board")
    add_hello_timeout(s)
    s.add_argument("--wheel", type=int, required=True, choices=range(4), help="wheel 0..3")
    s.add_argument("--speed", type=float, required=True, metavar="S", help="rad/s, |S| <= 20")
    s.add_argument("--time", type=float, default=3.0, metavar="T", help="s at speed (3, <= 10)")
    s.set_defaults(func=spin)


def calibrate(args) -> int:
    from gyrohost.bringup.devices import Target
    from gyrohost.bringup.wheels import calibrate_target
    from gyrohost.commands.errors import device_step

    port = args.port
    if args.old_port is not None:
        print("gyrotens wheels calibrate: PORT is deprecated, use --port PORT", file=sys.stderr)
        port = port or args.old_port
    target = Target(args.config, port, args.hello_timeout)
    wheels = sorted(set(args.wheel or range(4)))
    return device_step("wheels", lambda: calibrate_target(target, wheels, not args.no_save, say))


def spin(args) -> int:
    from gyrohost.bringup.devices import Target
    from gyrohost.bringup.wheels import spin_target
    from gyrohost.commands.errors import device_step

    target = Target(args.config, args.port, args.hello_timeout)
    return device_step(
        "wheels", lambda: spin_target(target, args.wheel, args.speed, args.time, say)
    )
