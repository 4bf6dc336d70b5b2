"""Figures of run files (matplotlib, Agg backend)."""

import json
import zipfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gyrohost.plots.errors import PlotError  # noqa: E402
from gyrohost.plots.styles import DASHES, MARKERS, colors, style  # noqa: E402
from gyrohost.resources import safe_name  # noqa: E402

MAX_POINTS = 4000
"""Samples drawn per line: five per pixel column of a 7-inch figure at 110 dpi; a longer run is
drawn at every k-th sample, and said so."""
MAX_ANIMATED = 1000
"""Bars and strings the GIF draws (each one a 3-D line in each of its 60 frames, about 1 ms
apiece): a larger scene's animation is left out, and said so."""


MAX_READ_BYTES = 1 << 30
"""Bytes of a run file's arrays the figures may read into memory (the animation's connectivity
matrices counted only when it is drawn): beyond, the file is refused before it is read."""
FIGURE_ARRAYS = ("t", "N", "node_names", "bar_length_error", "joint_error", "energy",
                 "angular_momentum", "scene")  # fmt: skip
ANIMATION_ARRAYS = ("C_b", "C_s")


class RunFile:
    """The arrays of a run file (``.npz``), each read when a figure first asks for it; their
    shapes known before any is read (from each member's ``.npy`` header).

    Raises
    ------
    PlotError
        The file cannot be read as a run file.
    """

    def __init__(self, path):
        self.path = Path(path)
        try:
            self._npz = np.load(self.path, allow_pickle=False)
            self.shapes = {name: self._header(name) for name in self._npz.files}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise PlotError(f"{self.path}: cannot read: {exc}") from None
        self._arrays: dict = {}

    def _header(self, name: str) -> tuple:
        with self._npz.zip.open(f"{name}.npy") as member:
            version = np.lib.format.read_magic(member)
            read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                    else np.lib.format.read_array_header_2_0)  # fmt: skip
            shape, _, dtype = read(member)
        return shape, dtype

    def nbytes(self, names) -> int:
        """Bytes of the arrays ``names`` (those in the file) once read."""
        return sum(
            int(np.prod(shape)) * dtype.itemsize
            for name, (shape, dtype) in self.shapes.items()
            if name in names
        )

    def rows(self, name: str) -> int:
        """Length of the array ``name`` (0 when the file has none)."""
        shape = self.shapes.get(name, ((0,), None))[0]
        return shape[0] if shape else 0

    def __getitem__(self, name: str):
        if name not in self._arrays:
            self._arrays[name] = self._npz[name]
        return self._arrays[name]

    def close(self) -> None:
        self._npz.close()


def max_traces() -> int:
    """Lines one figure tells apart: the styles (colour, dash pattern, marker) before one
    repeats; more nodes are drawn evenly picked, more bars as their largest error."""
    return int(np.lcm(len(colors()), np.lcm(len(DASHES), len(MARKERS))))


def _stride(n: int, most: int) -> int:
    """The step that leaves at most ``most`` of ``n`` items."""
    return max(-(-n // most), 1)


def _scene_nodes(run):
    """Indices of the primary node of each scene node (first occurrence), with names."""
    names = list(run["node_names"])
    seen = {}
    for i, n in enumerate(names):
        seen.setdefault(n, i)
    return list(seen.items())


def plot_nodes(run, path, warn=None, step: int = 1):
    """Node x, y, z against time (the paper's Fig. 7), every ``step``-th sample; with more
    nodes than :func:`max_traces`, that many evenly picked, said to ``warn``."""
    t, N = run["t"][::step], run["N"][::step]
    nodes = _scene_nodes(run)
    every = _stride(len(nodes), max_traces())
    if every > 1 and warn is not None:
        warn(f"{Path(path).name}: {len(nodes)} nodes, 1 in {every} drawn")
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7, 7))
    for k, (ax, label) in enumerate(zip(axes, "xyz", strict=True)):
        for j, (name, i) in enumerate(nodes[::every]):
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


def plot_constraints(run, path, warn=None, step: int = 1):
    """Bar-length and joint errors against time (the paper's Fig. 9), every ``step``-th sample;
    with more bars than :func:`max_traces`, their largest error, said to ``warn``."""
    t, bars = run["t"][::step], run["bar_length_error"][::step]
    fig, ax = plt.subplots(figsize=(7, 4))
    n_bars = bars.shape[1]
    if n_bars > max_traces():
        if warn is not None:
            warn(f"{Path(path).name}: {n_bars} bars, drawn as their largest error")
        _log_abs(ax, t, np.abs(bars).max(axis=1), "bars (max)", **style(0, len(t)))
        n_bars = 1
    else:
        for i in range(n_bars):
            _log_abs(ax, t, bars[:, i], f"bar {i + 1}", **style(i, len(t)))
    if run["joint_error"].shape[1]:
        joints = run["joint_error"][::step].max(axis=1)
        _log_abs(ax, t, joints, "joints (max)", **style(n_bars, len(t)))
    ax.set_xlabel("t (s)")
    ax.set_ylabel("|error| (m)")
    ax.legend(fontsize="small")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_invariants(run, path, step: int = 1):
    """Relative drift of the total energy and of the angular momentum, every ``step``-th
    sample."""
    t, E, H = run["t"][::step], run["energy"][::step], run["angular_momentum"][::step]
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


def plot_run_file(path, out, animation=True, warn=None) -> list:
    """:func:`plot_run` of the run file at ``path``, its arrays read as the figures need them.

    Raises
    ------
    PlotError
        The file cannot be read, or the arrays the figures need take more than
        :data:`MAX_READ_BYTES` in memory (the message says how much).
    """
    run = RunFile(path)
    try:
        animation = animation and _animated(run, warn)
        need = FIGURE_ARRAYS + (ANIMATION_ARRAYS if animation else ())
        size = run.nbytes(need)
        if size > MAX_READ_BYTES:
            raise PlotError(
                f"{path}: its figures would read {size / 1e9:.1f} GB of arrays, more than "
                f"{MAX_READ_BYTES / 1e9:.1f} GB: plot a shorter run or one sampled less often "
                "(a larger sample_dt in the scene)"
            )
        return plot_run(run, out, animation, warn)
    finally:
        run.close()


def _animated(run: RunFile, warn) -> bool:
    """Whether the scene of ``run`` is small enough to animate (:data:`MAX_ANIMATED`); if not,
    said to ``warn``."""
    members = run.rows("C_b") + run.rows("C_s")
    if members <= MAX_ANIMATED:
        return True
    if warn is not None:
        warn(f"animation left out: {members} bars and strings, more than {MAX_ANIMATED}")
    return False


def plot_run(run, out, animation=True, warn=None):
    """Write all figures of a run into folder ``out``; returns the paths written.

    A run too long to draw whole is drawn thinned (:data:`MAX_POINTS` samples a line, at most
    :func:`max_traces` lines a figure), said to ``warn``.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    name = safe_name(json.loads(str(run["scene"])).get("name", "run"))
    paths = [out / f"{name}-nodes.png", out / f"{name}-constraints.png"]
    paths.append(out / f"{name}-invariants.png")
    n = len(run["t"])
    step = _stride(n, MAX_POINTS)
    if step > 1 and warn is not None:
        warn(f"{n} samples, 1 in {step} drawn")
    plot_nodes(run, paths[0], warn, step)
    plot_constraints(run, paths[1], warn, step)
    plot_invariants(run, paths[2], step)
    if animation:
        paths.append(out / f"{name}.gif")
        animate(run, paths[-1])
    return paths
