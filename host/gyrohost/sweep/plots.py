"""Figures of a sweep: a quantity over two axes (heat map), the Pareto front of cost and goal."""

from pathlib import Path

import numpy as np

from .spec import Spec


def _figure():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt, *plt.subplots(figsize=(6.4, 4.8), layout="constrained")


def _column(rows, name) -> np.ndarray:
    """Column ``name`` of the finished cases as floats (NaN where missing or not a number)."""
    return np.array(
        [v if isinstance(v := r.get(name), int | float) else np.nan for r in rows], dtype=float
    )


def heatmap(spec: Spec, rows: list, path: Path) -> Path | None:
    """``spec.heatmap`` over the first two axes (grid: cells; Latin hypercube: coloured points),
    with the level ``spec.contour`` drawn; None unless the sweep has exactly two axes."""
    if len(spec.axes) != 2:
        return None
    xa, ya = spec.axes
    x, y, z = (_column(rows, n) for n in (xa.name, ya.name, spec.heatmap))
    plt, fig, ax = _figure()
    if spec.sampling == "grid":
        xs, ys = sorted(set(xa.values)), sorted(set(ya.values))
        Z = np.full((len(ys), len(xs)), np.nan)
        for xv, yv, zv in zip(x, y, z, strict=True):
            Z[ys.index(yv), xs.index(xv)] = zv
        mesh = ax.pcolormesh(xs, ys, Z, shading="nearest", cmap="viridis")
        if spec.contour is not None and np.nanmin(Z) < spec.contour < np.nanmax(Z):
            lines = ax.contour(xs, ys, Z, levels=[spec.contour], colors="w", linestyles="solid")
            ax.clabel(lines, fmt=f"{spec.heatmap} = {spec.contour:g}")
    else:
        mesh = ax.scatter(x, y, c=z, cmap="viridis", s=18)
    fig.colorbar(mesh, ax=ax, label=spec.heatmap)
    ax.set_xlabel(xa.name)
    ax.set_ylabel(ya.name)
    ax.set_title(f"{spec.name}: {spec.heatmap} ({np.isfinite(z).sum()} of {len(rows)} cases)")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def goal_score(spec: Spec, rows: list) -> np.ndarray:
    """What the Pareto front minimises besides the cost: |goal - target|, goal ('min') or
    -goal ('max'), one per row."""
    p = spec.pareto
    goal = _column(rows, p["goal"])
    if "target" in p:
        return np.abs(goal - p["target"])
    return goal if p["sense"] == "min" else -goal


def pareto_front(cost: np.ndarray, score: np.ndarray) -> np.ndarray:
    """Indices of the non-dominated points (lower cost and lower score both better), by cost."""
    ok = np.flatnonzero(np.isfinite(cost) & np.isfinite(score))
    order = ok[np.lexsort((score[ok], cost[ok]))]
    front, best = [], np.inf
    for k in order:
        if score[k] < best:
            front.append(k)
            best = score[k]
    return np.array(front, dtype=int)


def pareto(spec: Spec, rows: list, path: Path) -> Path | None:
    """Cost against the goal's score for every finished case, the front marked; None without
    a ``[pareto]`` table."""
    if spec.pareto is None:
        return None
    p = spec.pareto
    cost, score = _column(rows, p["cost"]), goal_score(spec, rows)
    front = pareto_front(cost, score)
    plt, fig, ax = _figure()
    ax.scatter(cost, score, s=12, color="0.6", label="cases")
    ax.plot(cost[front], score[front], "o-", color="C3", label="Pareto front")
    ylabel = f"|{p['goal']} - target| (target {p['target']:g})" if "target" in p else p["goal"]
    if p.get("sense") == "max":
        ylabel = f"-{p['goal']}"
    ax.set_xlabel(f"{p['cost']} (cost)")
    ax.set_ylabel(ylabel)
    ax.legend()
    ax.set_title(f"{spec.name}: Pareto front ({len(front)} cases)")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
