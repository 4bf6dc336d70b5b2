"""Figures of run files (matplotlib, Agg backend)."""

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gyrohost.plots.styles import style  # noqa: E402
from gyrohost.resources import safe_name  # noqa: E402


def _scene_nodes(run):
    """Indices of the primary node of each scene node (first occurrence), with names."""
    names = list(run["node_names"])
    seen = {}
    for i, n in enumerate(names):
        seen.setdefault(n, i)
    return list(seen.items())


def plot_nodes(run, path):
    """Node x, y, z against time (the paper's Fig. 7)."""
    t, N = run["t"], run["N"]
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7, 7))
    for k, (ax, label) in enumerate(zip(axes, "xyz", strict=True)):
        for j, (name, i) in enumerate(_scene_nodes(run)):
            ax.plot(t, N[:, k, i], label=name, **style(j, len(t)))
        ax.set_ylabel(f"{label} (m)")
        ax.grid(True, alpha=0.3)
    axes[0].legend(ncol=4, fontsize="small")
    axes[-1].set_xlabel("t (s)")
    fig.suptitle("node coordinates")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _log_abs(ax, t, y, label, **kw):
    ax.semilogy(t, np.maximum(np.abs(y), 1e-18), label=label, **kw)


def plot_constraints(run, path):
    """Bar-length and joint errors against time (the paper's Fig. 9)."""
    t = run["t"]
    fig, ax = plt.subplots(figsize=(7, 4))
    for i in range(run["bar_length_error"].shape[1]):
        _log_abs(ax, t, run["bar_length_error"][:, i], f"bar {i + 1}", **style(i, len(t)))
    if run["joint_error"].shape[1]:
        n_bars = run["bar_length_error"].shape[1]
        _log_abs(ax, t, run["joint_error"].max(axis=1), "joints (max)", **style(n_bars, len(t)))
    ax.set_xlabel("t (s)")
    ax.set_ylabel("|error| (m)")
    ax.legend(fontsize="small")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_invariants(run, path):
    """Relative drift of the total energy and of the angular momentum."""
    t, E, H = run["t"], run["energy"], run["angular_momentum"]
    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
    scale_e = max(abs(E[0]), 1e-300)
    scale_h = max(np.linalg.norm(H[0]), 1e-300)
    _log_abs(axes[0], t, (E - E[0]) / scale_e, "energy")
    _log_abs(axes[1], t, np.linalg.norm(H - H[0], axis=1) / scale_h, "angular momentum")
    axes[0].set_ylabel("|E - E0| / |E0|")
    axes[1].set_ylabel("|H - H0| / |H0|")
    axes[1].set_xlabel("t (s)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def animate(run, path, frames=60):
    """GIF of the bars (thick) and strings (thin) in 3-D."""
    from matplotlib.animation import PillowWriter

    N, C_b, C_s, t = run["N"], run["C_b"], run["C_s"], run["t"]
    ends = [(np.flatnonzero(row < 0)[0], np.flatnonzero(row > 0)[0]) for row in C_b]
    strings = [(np.flatnonzero(row < 0)[0], np.flatnonzero(row > 0)[0]) for row in C_s]
    lo, hi = N.min(axis=(0, 2)), N.max(axis=(0, 2))
    centre, half = (lo + hi) / 2, max(np.max(hi - lo) / 2, 1e-3)
    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(projection="3d")
    writer = PillowWriter(fps=15)
    with writer.saving(fig, str(path), dpi=80):
        for k in np.linspace(0, len(t) - 1, min(frames, len(t))).astype(int):
            ax.cla()
            for a, b in ends:
                ax.plot(*N[k][:, [a, b]], color="k", linewidth=3)
            for a, b in strings:
                ax.plot(*N[k][:, [a, b]], color="tab:red", linewidth=1)
            for axis, c in zip("xyz", centre, strict=True):
                getattr(ax, f"set_{axis}lim")(c - half, c + half)
            ax.set_title(f"t = {t[k]:.2f} s")
            writer.grab_frame()
    plt.close(fig)


def plot_run(run, out, animation=True):
    """Write all figures of a run into folder ``out``; returns the paths written."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    name = safe_name(json.loads(str(run["scene"])).get("name", "run"))
    paths = [out / f"{name}-nodes.png", out / f"{name}-constraints.png"]
    paths.append(out / f"{name}-invariants.png")
    plot_nodes(run, paths[0])
    plot_constraints(run, paths[1])
    plot_invariants(run, paths[2])
    if animation:
        paths.append(out / f"{name}.gif")
        animate(run, paths[-1])
    return paths
