"""The options of ``gyrotens sil`` and the studies that score the estimator.

A module of its own that imports neither numpy nor the model, so that registering ``sil`` keeps
``gyrotens --help`` fast.
"""

from pathlib import Path

from gyrohost import parallel
from gyrohost.resources import shipped

DEFAULT_CONFIG = shipped("config", "sim-rig")


def add_arguments(parser) -> None:
    """The options of ``gyrotens sil`` and of the experiment's command line."""
    parser.add_argument(
        "--runs", type=int,
        help="simulated runs scored (20; --score-only: every run recorded in OUT)",
    )  # fmt: skip
    parser.add_argument("--config", type=Path, default=DEFAULT_CONFIG, help="rig configuration")
    parser.add_argument(
        "--overlay", type=Path, action="append", default=[], metavar="FILE",
        help="TOML keys merged into the configuration (as gyrotens identify writes them); "
        "may be repeated",
    )  # fmt: skip
    parser.add_argument("--scene", help="the host's scene (default: the configuration's)")
    parser.add_argument(
        "--truth-scene", metavar="FILE",
        help="the scene the simulated rig's truth runs (default: [sim.truth] scene)",
    )  # fmt: skip
    parser.add_argument("--duration", type=float, default=3.0, help="schedule length, s")
    parser.add_argument("--realtime", action="store_true", help="real-time rig via the run loop")
    parser.add_argument(
        "-o", "--out", type=Path, default=Path("out/sil"), help="logs (--realtime; out/sil)"
    )
    parser.add_argument("--score-only", action="store_true", help="score existing logs in OUT")
    parser.add_argument(
        "--estimator",
        type=Path,
        metavar="FILE",
        help="TOML with an [estimator] table whose keys override the rig configuration's "
        "(simulated clock; --realtime: recording) or the logs' (--score-only: replayed with them)",
    )
    parser.add_argument(
        "--plot",
        type=Path,
        metavar="FILE",
        help="the step-by-step NEES/NIS figure (PNG; default OUT/consistency.png)",
    )
    parallel.add_arguments(parser, serial_default=True)  # simulated clock only
