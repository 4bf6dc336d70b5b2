"""``gyrotens servos id|zero`` (formerly ``gyrotens servo-setup id|zero``, kept with a
deprecation line): a lone servo's ID and baud rate; the zero of a servo's length model, moved
only after a confirmation (docs/bring-up.md, docs/rig-config.md)."""

import sys
from functools import partial

from gyrohost.commands.devices import add_device_options


def register(sub) -> None:
    p = sub.add_parser("servo-setup", help="deprecated: gyrotens servos id|zero")
    add_steps(p.add_subparsers(dest="step", metavar="STEP", required=True), old=True)


def add_steps(steps, old: bool = False) -> None:
    """The ``id`` and ``zero`` verbs on the argparse subparsers ``steps`` (``gyrotens servos``;
    with ``old``, ``gyrotens servo-setup``, which says it is deprecated when run)."""
    ids = steps.add_parser("id", help="give the only servo on the bus a new ID (and baud rate)")
    add_device_options(ids, "U2D2")  # with one servo on its bus
    ids.add_argument("--baud", type=int, default=1_000_000, help="its baud rate now (1000000)")
    ids.add_argument("--new-id", type=int, required=True, metavar="ID", help="its ID: 0..252")
    ids.add_argument(
        "--new-baud", type=int, metavar="BAUD", help="its baud rate afterwards (default: unchanged)"
    )
    ids.add_argument(
        "--scan-ids", default="0-252", metavar="A-B", help="IDs searched (0-252: every one)"
    )
    ids.add_argument(
        "--reply-timeout",
        type=float,
        default=0.034,
        metavar="S",
        help="wait for each reply beyond its transfer time (0.034 s)",
    )
    ids.set_defaults(func=partial(_deprecated, "id", run_id) if old else run_id)
    zero = steps.add_parser("zero", help="read a servo's zero_position, check its length_sign")
    zero.add_argument("--config", required=True, help="rig configuration: a TOML file or name")
    zero.add_argument("--port", help="the U2D2's serial port (overrides the configuration's)")
    zero.add_argument("--servo", required=True, metavar="NAME", help="servo name, e.g. s13")
    zero.add_argument("--length-m", type=float, metavar="M", help="the length measured (asked)")
    zero.add_argument(
        "--check-m", type=float, default=0.01, metavar="M", help="length_sign test move (0.01 m)"
    )
    zero.add_argument("--yes", action="store_true", help="move without asking")
    zero.set_defaults(func=partial(_deprecated, "zero", run_zero) if old else run_zero)


def _deprecated(verb: str, step, args) -> int:
    print(f"gyrotens servo-setup {verb}: deprecated, use gyrotens servos {verb}", file=sys.stderr)
    return step(args)


def _id_range(text: str) -> range:
    from gyrohost.commands.errors import CliError

    try:
        lo, _, hi = text.partition("-")
        ids = range(int(lo), int(hi or lo) + 1)
    except ValueError:
        raise CliError(f"--scan-ids {text!r}: expected A-B, e.g. 1-10") from None
    if not ids or ids.start < 0 or ids.stop > 253:
        raise CliError(f"--scan-ids {text!r}: IDs are 0..252")
    return ids


def run_id(args) -> int:
    from gyrohost.bringup.devices import Target
    from gyrohost.bringup.servo_setup import change_id
    from gyrohost.commands.errors import CliError
    from gyrohost.errors import GyrohostError

    ids = _id_range(args.scan_ids)
    try:
        port = Target(args.config, args.port).rig("servos").servos.port
        change = change_id(port, args.baud, args.new_id, args.new_baud, ids,
                           args.reply_timeout)  # fmt: skip
    except (GyrohostError, OSError) as exc:
        raise CliError(str(exc)) from None
    print(change.describe())
    return 0


def ask(question: str) -> bool:
    """``question [y/N]`` on the terminal; True for y or yes."""
    return input(f"{question} [y/N] ").strip().lower() in ("y", "yes")


def run_zero(args) -> int:
    from dataclasses import replace

    from gyrohost.bringup.devices import Target
    from gyrohost.bringup.servo_setup import check_sign, read_zero
    from gyrohost.commands.errors import CliError
    from gyrohost.errors import GyrohostError

    try:
        config = Target(args.config, args.port).rig("servos")
        by_name = {s.name: (i, s) for i, s in enumerate(config.servos.servo)}
        if args.servo not in by_name:
            raise CliError(f"{config.source}: no servo named {args.servo!r} ({sorted(by_name)})")
        index, servo = by_name[args.servo]
        zero, length_m = read_zero(config.servos, servo, partial(_measured, servo, args.length_m))
        servo = replace(servo, zero_position=zero, length_at_zero_m=length_m)
        confirm = (lambda _q: True) if args.yes else ask
        goal, moved = check_sign(config.servos, servo, args.check_m, config.run.max_servo_load,
                                 confirm)  # fmt: skip
        as_asked = ask(f"moved {moved:+d} steps: did the string get {_word(goal > length_m)}?")
    except (GyrohostError, OSError, ValueError) as exc:
        raise CliError(str(exc)) from None
    sign = servo.length_sign if as_asked else -servo.length_sign
    print(f'\nin [[servos.servo]] {index} of {config.source} (name = "{servo.name}"):')
    print(f"zero_position = {zero}\nlength_at_zero_m = {length_m:g}\nlength_sign = {sign}")
    sys.stdout.flush()
    return 0


def _measured(servo, length_m: float | None) -> float:
    """Said once the servo's torque is off: the length given, or the one the user measures."""
    print(f"servo '{servo.name}' (ID {servo.id}): torque off", flush=True)
    if length_m is not None:
        return length_m
    return float(input("wind its string by hand, then the length between its nodes, m: "))


def _word(longer: bool) -> str:
    return "longer" if longer else "shorter"
