"""``gyrotens plot FILE -o DIR``: figures of a recorded file, dispatched on the file's type.

Run files of the dynamics model (.npz with ``N`` and ``node_names``) and run logs of the rig (a
folder with ``meta.json``, written by ``gyrotens run``; figures in ``gyrohost.plots.log``).
"""

from pathlib import Path
from zipfile import BadZipFile


def register(sub) -> None:
    p = sub.add_parser("plot", help="write PNG figures of a run file or a run log")
    p.add_argument(
        "file", type=Path, help="run file (.npz) of 'gyrotens simulate' or log folder of 'run'"
    )
    p.add_argument("-o", "--out", type=Path, help="output folder (default: LOG/plots for a log)")
    p.add_argument("--no-animation", action="store_true", help="skip the GIF animation")
    p.set_defaults(func=run)


def _is_run_file(path: Path) -> bool:
    import numpy as np

    if path.suffix != ".npz":
        return False
    with np.load(path, allow_pickle=False) as z:
        return {"N", "node_names", "t"} <= set(z.files)


def _plot_run(args):
    from gyrohost.commands.errors import CliError
    from gyrohost.commands.replay import Warnings
    from gyrohost.plots.errors import PlotError
    from gyrohost.plots.model import plot_run_file

    warn = Warnings("plot")
    try:
        paths = plot_run_file(args.file, args.out, not args.no_animation, warn)
    except PlotError as exc:
        raise CliError(str(exc)) from None
    warn.close()
    return paths


def _is_log(path: Path) -> bool:
    return path.is_dir() and (path / "meta.json").is_file()


def _plot_log(args):
    from gyrohost.commands.errors import CliError
    from gyrohost.commands.replay import Warnings
    from gyrohost.plots.log import plot_log

    out = args.out or args.file / "plots"
    warn = Warnings("plot")
    paths = plot_log(args.file, out, warn)
    warn.close()
    if not paths:
        raise CliError(f"{args.file}: no stream with rows to plot; nothing written")
    return paths


PLOTTERS = [(_is_run_file, _plot_run), (_is_log, _plot_log)]


def run(args) -> int:
    from gyrohost.commands.errors import CliError
    from gyrohost.run.errors import LogError
    from gyrohost.run.log import check_output_folder

    if not args.file.exists():
        raise CliError(f"{args.file}: no such file or folder")
    for accepts, plot in PLOTTERS:
        try:
            ok = accepts(args.file)
        except (OSError, ValueError, EOFError, BadZipFile) as exc:  # a damaged .npz among them
            raise CliError(f"{args.file}: cannot read: {exc or type(exc).__name__}") from None
        if ok:
            if args.out is None and not args.file.is_dir():
                raise CliError("give the output folder with -o")
            try:
                check_output_folder(args.out or args.file / "plots")
                paths = plot(args)
            except LogError as exc:
                raise CliError(str(exc)) from None
            for path in paths:
                print(path)
            return 0
    raise CliError(
        f"{args.file}: not a file type 'plot' knows (run files: .npz from simulate; "
        "log folders with meta.json from run)"
    )
