"""``gyrotens plot FILE -o DIR``: figures of a recorded file, dispatched on the file's type.

Run files of the dynamics model (.npz with ``N`` and ``node_names``) are supported now; rig
logs will get their own entry in ``PLOTTERS``.
"""

from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("plot", help="write PNG figures (and a GIF) of a run file")
    p.add_argument("file", type=Path, help="run file (.npz) written by 'gyrotens simulate'")
    p.add_argument("-o", "--out", type=Path, required=True, help="output folder")
    p.add_argument("--no-animation", action="store_true", help="skip the GIF animation")
    p.set_defaults(func=run)


def _is_run_file(path: Path) -> bool:
    import numpy as np

    if path.suffix != ".npz":
        return False
    with np.load(path, allow_pickle=False) as z:
        return {"N", "node_names", "t"} <= set(z.files)


def _plot_run(args):
    from gyrohost import plots
    from gyrotensegrity import load_run

    return plots.plot_run(load_run(args.file), args.out, animation=not args.no_animation)


PLOTTERS = [(_is_run_file, _plot_run)]


def run(args) -> int:
    from gyrohost.cli import CliError

    if not args.file.is_file():
        raise CliError(f"{args.file}: no such file")
    for accepts, plot in PLOTTERS:
        try:
            ok = accepts(args.file)
        except (OSError, ValueError) as exc:
            raise CliError(f"{args.file}: cannot read: {exc}") from None
        if ok:
            for path in plot(args):
                print(path)
            return 0
    raise CliError(f"{args.file}: not a file type 'plot' knows (run files: .npz from simulate)")
