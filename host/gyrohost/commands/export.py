"""``gyrotens export LOG [-o FILE]``: a log folder's CSV streams as an MCAP file (one
channel per stream, JSON schemas, the 3D scenes; docs/run.md), e.g. for a run that was killed
before its own ``run.mcap`` was finished."""

from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("export", help="convert a run log to another format (MCAP)")
    p.add_argument("log", type=Path, help="log folder (meta.json + CSV streams)")
    p.add_argument(
        "--mcap", action="store_true", help="write an MCAP file (Foxglove; the only format)"
    )
    p.add_argument(
        "-o",
        "--out",
        type=Path,
        metavar="FILE",
        help="output file (default: LOG/run.mcap, replaced)",
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from gyrohost.commands.errors import CliError
    from gyrohost.commands.replay import Warnings
    from gyrohost.run.errors import LogError
    from gyrohost.run.log import check_output_folder
    from gyrohost.run.mcap import export_mcap

    warn = Warnings("export")
    try:
        if args.out is not None:
            check_output_folder(args.out.parent)
        path = export_mcap(args.log, args.out, warn)
    except LogError as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f"{args.out or args.log}: cannot write: {exc.strerror or exc}") from None
    warn.close()
    print(f"wrote {path}")
    return 0
