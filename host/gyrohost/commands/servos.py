"""``gyrotens servos id|zero|jog|home``: a servo's ID and its zero (:mod:`.servo_setup`); one
string lengthened or shortened by a given length, every string driven to the scene's start
length, within the configured limits (docs/bring-up.md)."""

from gyrohost.commands.devices import add_device_options, say
from gyrohost.commands.servo_setup import add_steps


def register(sub) -> None:
    p = sub.add_parser(
        "servos", help="the string servos: set an ID, calibrate a zero, jog one, drive all home"
    )
    actions = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    add_steps(actions)
    j = actions.add_parser("jog", help="lengthen (+) or shorten (-) one string, then hold")
    add_device_options(j, "servo bus (U2D2)")
    j.add_argument("--servo", required=True, metavar="NAME", help="servo name, e.g. s13")
    j.add_argument("--by-m", type=float, required=True, metavar="D", help="length change, m")
    j.set_defaults(func=jog)
    h = actions.add_parser("home", help="drive every string to the scene's start length, hold")
    add_device_options(h, "servo bus (U2D2)")
    h.set_defaults(func=home)


def jog(args) -> int:
    from gyrohost.bringup import servo_moves
    from gyrohost.bringup.devices import Target
    from gyrohost.commands.errors import device_step

    target = Target(args.config, args.port)
    return device_step("servos", lambda: servo_moves.jog(target, args.servo, args.by_m, say))


def home(args) -> int:
    from gyrohost.bringup import servo_moves
    from gyrohost.bringup.devices import Target
    from gyrohost.commands.errors import device_step

    return device_step("servos", lambda: servo_moves.home(Target(args.config, args.port), say))
