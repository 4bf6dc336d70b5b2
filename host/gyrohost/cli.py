"""The ``gyrotens`` command line: one entry point, one module per subcommand.

Each module named in ``COMMANDS`` lives in ``gyrohost.commands`` and provides
``register(subparsers)``, which adds its parser and sets ``func`` to a callable
``func(args) -> int`` (the exit status). A subcommand raises ``CliError`` for a
user mistake; the message is printed without a traceback and the exit status is 2.
"""

import argparse
import importlib
import sys

from gyrohost.commands.errors import CliError

COMMANDS = [
    "demo",
    "simulate",
    "plan",
    "plot",
    "rig",
    "run",
    "replay",
    "export",
    "bench",
    "ports",
    "doctor",
    "servo-setup",
    "sil",
    "sweep",
    "wheels",
    "servos",
    "imu",
    "identify",
    "noise",
]


class _VersionAction(argparse.Action):
    """``--version``: print the version and exit; looked up only when asked for."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, help="show the version and exit")

    def __call__(self, parser, namespace, values, option_string=None):
        from gyrohost import version

        print(f"gyrotens {version()}")
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gyrotens",
        description="Gyroscopic tensegrity robots: simulate, benchmark, run the rig.",
    )
    parser.add_argument("--version", action=_VersionAction)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"gyrohost.commands.{name.replace('-', '_')}").register(sub)
    parser.command_parsers = sub.choices  # name -> its parser, which reports its bad options
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args, unknown = parser.parse_known_args(argv)
    if unknown:  # said by the subcommand's parser: its usage, "gyrotens CMD: error: ..."
        command = parser.command_parsers.get(args.command, parser)
        command.error(f"unrecognized arguments: {' '.join(unknown)}")
    if not hasattr(args, "func"):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except CliError as exc:
        print(f"gyrotens {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"gyrotens {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
