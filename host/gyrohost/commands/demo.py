"""``gyrotens demo``: the paper's D-bar experiment end to end, writing logs and plots."""

from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("demo", help="run the paper's D-bar experiment and write logs and plots")
    p.add_argument("-o", "--out", type=Path, default=Path("out/demo"), help="output folder")
    p.set_defaults(func=run)


def run(args) -> int:
    from gyrohost.cli import CliError

    raise CliError("the demo needs the dynamics model, which is not built yet (issue 3)")
