"""The estimator's consistency over N runs, step by step (``gyrotens sil``'s figure).

One panel of the N-run average NEES at every scored step and one of the N-run average NIS of
each source at every sample, on a log scale, each with the two-sided 95 % chi-square bounds
of an N-run average shaded (the caller gives them:
:func:`gyrohost.estimator.consistency.average_bounds`), its dof dashed and, in the legend, its
mean and the share of steps inside the bounds.
"""

from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter  # noqa: E402

DPI = 110


@dataclass
class Series:
    """A run-averaged NEES or NIS: ``values`` (k,) at ``t_s`` (k,), s, with ``dof`` and the
    95 % ``bounds`` (lower, upper) of the average."""

    name: str
    t_s: np.ndarray
    values: np.ndarray
    dof: int
    bounds: tuple


def _panel(ax, series: Series) -> None:
    lo, hi = series.bounds
    inside = float(np.mean((series.values >= lo) & (series.values <= hi)))
    ax.axhspan(lo, hi, color="0.85", label=f"95 % bounds [{lo:.2f}, {hi:.2f}]")
    ax.axhline(series.dof, color="0.4", ls="--", lw=0.8, label=f"dof {series.dof}")
    ax.semilogy(
        series.t_s,
        series.values,
        lw=1.0,
        label=f"mean {np.mean(series.values):.2f}; {100 * inside:.1f} % of steps inside",
    )
    ax.set_ylabel(series.name)
    ax.set_ylim(*_y_range(series.values, lo, hi))
    ax.yaxis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))  # within a decade too
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0))


def _y_range(values, lo: float, hi: float) -> tuple[float, float]:
    """The panel's log range: the bounds and the values, down to a thirtieth of the lower bound
    at most (a first NIS of nearly 0 would stretch the axis over hundreds of decades and leave
    it without a labelled tick)."""
    finite = values[np.isfinite(values)]
    floor = lo / 30.0
    low = max(float(np.min(finite, initial=lo)), floor)
    return min(low, lo) / 1.5, max(float(np.max(finite, initial=hi)), hi) * 1.5


def figure_consistency(nees: Series, nis: list[Series], runs: int, title: str):
    """The figure (unsaved) of the run-averaged ``nees`` and the ``nis`` of every source."""
    n = 1 + len(nis)
    fig, axes = plt.subplots(
        n, 1, figsize=(10, 2.8 + 1.5 * n), gridspec_kw={"height_ratios": [2] + [1] * len(nis)}
    )
    axes = np.atleast_1d(axes)
    _panel(axes[0], nees)
    axes[0].set_xlabel("t from the first IMU sample (s)")
    for ax, series in zip(axes[1:], nis, strict=True):
        _panel(ax, series)
    if nis:
        axes[-1].set_xlabel("t from the source's first sample (s)")
    fig.suptitle(f"{title}: {runs}-run average, step by step")
    fig.tight_layout()
    return fig


def plot_consistency(nees: Series, nis: list[Series], runs: int, title: str, path) -> Path:
    """:func:`figure_consistency` written to ``path`` (PNG; its folder made if missing)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig = figure_consistency(nees, nis, runs, title)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path
