"""The SIL's step-by-step figure draws the N-run average of NEES and NIS at every step with the
95 % bounds of an N-run average (made-up runs: known averages, bounds from scipy directly)."""

import numpy as np
from scipy.stats import chi2

from gyrohost.plots.consistency import figure_consistency, plot_consistency
from gyrohost.sil.montecarlo import ScoredRun
from gyrohost.sil.scoring import consistency_series


def _runs():
    rng = np.random.default_rng(5)
    out = []
    for k in (50, 48, 52):  # runs of unequal length: the average is over the shortest
        t = 0.01 * np.arange(k)
        nis = {"imu_rate": (1.2 + t, rng.chisquare(3, k), np.full(k, 3))}
        out.append(ScoredRun(t, rng.chisquare(14, k), 14, t, t, nis, 0.1))
    return out


def test_figure_draws_the_run_average_at_every_step_with_its_bounds(tmp_path):
    runs = _runs()
    nees, nis = consistency_series(runs)
    fig = figure_consistency(nees, nis, len(runs), "test")
    for ax, dof, values in (
        (fig.axes[0], 14, [r.nees[:48] for r in runs]),
        (fig.axes[1], 3, [r.nis["imu_rate"][1][:48] for r in runs]),
    ):
        (line,) = [ln for ln in ax.get_lines() if "of steps inside" in ln.get_label()]
        assert np.allclose(line.get_xdata(), 0.01 * np.arange(48))  # from the first sample
        mean = np.mean(values, axis=0)
        assert np.allclose(line.get_ydata(), mean)
        lo, hi = chi2.ppf([0.025, 0.975], 3 * dof) / 3
        (span,) = ax.patches
        assert np.isclose(span.get_y(), lo) and np.isclose(span.get_y() + span.get_height(), hi)
        inside = 100 * np.mean((mean >= lo) & (mean <= hi))
        assert line.get_label().endswith(f"{inside:.1f} % of steps inside")
    assert [ax.get_ylabel() for ax in fig.axes] == ["NEES", "NIS imu_rate"]
    path = plot_consistency(nees, nis, len(runs), "test", tmp_path / "new" / "c.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_near_zero_first_value_leaves_the_axis_its_labelled_ticks():
    runs = _runs()
    for r in runs:
        r.nis["imu_rate"][1][0] = 1e-300  # a first innovation of nothing
    nees, nis = consistency_series(runs)
    fig = figure_consistency(nees, nis, len(runs), "test")
    ax = fig.axes[1]
    bottom, top = ax.get_ylim()
    lo, hi = chi2.ppf([0.025, 0.975], 9) / 3
    assert lo / 50 < bottom < lo and hi < top < 100 * hi
    fig.canvas.draw()
    labels = [t.get_text() for t in ax.get_yticklabels() if bottom <= t.get_position()[1] <= top]
    assert len([t for t in labels if t]) >= 2
