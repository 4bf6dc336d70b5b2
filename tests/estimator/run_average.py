"""Test helper: is a run-averaged NEES or NIS inside the 95 % bounds of its average?"""

import numpy as np

from gyrohost.estimator.consistency import average_bounds


def inside_bounds(values, dof, runs):
    """(inside, message) for the mean of ``values`` (per run: arrays or scalars) against the
    95 % chi-square bounds of a ``runs``-run average of ``dof`` degrees of freedom."""
    lo, hi = average_bounds(dof, runs)
    mean = float(np.mean(values))
    return lo <= mean <= hi, f"{mean:.2f} not in [{lo:.2f}, {hi:.2f}] (dof {dof}, {runs} runs)"


def share_inside(series, dof, runs):
    """Share of the time steps at which the ``runs``-run average of ``series`` (per run: arrays
    over the same steps, cut to the shortest) lies inside the 95 % bounds of its average."""
    k = min(len(v) for v in series)
    avg = np.mean([v[:k] for v in series], axis=0)
    lo, hi = average_bounds(dof, runs)
    return float(np.mean((avg >= lo) & (avg <= hi)))
