"""Figures of a run log (``gyrotens plot LOGDIR``): the paper's Figs. 7 and 8 and diagnostics.

Every figure has time on the host clock of the run (``t_s``, s) and marks where the schedule
started; estimate lines are solid, truth lines (simulated rig only) dashed in the same colour. A log
without a truth (a separate rig process, real hardware) is titled "estimate" only.

The figures follow the scene, as the log holds it: a D-bar log (its ``nodes`` stream has a
``tilt_rad`` column) gets the paper's figures of the plane nodes and the tilt; any other scene
gets every node's coordinates, the IMU's angles, wheels, innovations and loop timing
(:func:`plots_for`). A figure whose streams are all missing or empty (a replay's log, a damaged
log) is left out and said so: no figure is written empty.
"""

from collections.abc import Callable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gyrohost.control.attitude import PLANE_NODES  # noqa: E402
from gyrohost.run.log import read_meta, read_streams  # noqa: E402

INNOVATION_SOURCES = ("imu_rate", "imu_accel", "imu_angle", "wheels", "servos")
DPI = 110


class RunData:
    """The streams of one log folder, read once (missing streams are ``None``).

    Without ``warn`` a stream that cannot be read raises ``LogError``; with it, unreadable rows
    are skipped and a stream whose file is missing or empty is left out, each told to ``warn``
    (:func:`gyrohost.run.log.read_stream`).
    """

    def __init__(self, folder, warn: Callable[[str], None] | None = None):
        self.folder = Path(folder)
        self.meta = read_meta(self.folder)
        self.streams = read_streams(self.folder, self.meta.get("streams", {}), warn)
        self.has_truth = self.get("truth") is not None
        """The log holds the simulated rig's truth (a run with ``--sim``)."""
        events = self.streams.get("events")
        starts = [] if events is None else events["t_s"][events["message"] == "schedule"]
        self.t_schedule = float(starts[0]) if len(starts) else None
        self.title = Path(str(self.meta.get("scene", self.folder.name))).stem
        nodes = self.streams.get("nodes")
        if nodes is None:
            nodes = self.streams.get("truth")
        columns = () if nodes is None else nodes.dtype.names
        self.dbar = "tilt_rad" in columns
        """The log is of a D-bar scene (it has the plane's tilt)."""
        scene_nodes = [c[: -len("_x_m")] for c in columns if c.endswith("_x_m")]
        self.nodes = PLANE_NODES if self.dbar else tuple(scene_nodes)
        """The nodes the figures show: the D-bar's plane nodes, else every scene node."""

    def get(self, name):
        s = self.streams.get(name)
        return s if s is not None and len(s) else None


def _finish(fig, axes, data, path) -> Path:
    for ax in np.ravel(axes):
        if data.t_schedule is not None:
            ax.axvline(data.t_schedule, color="0.5", lw=0.8, ls=":")
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def _colors():
    return plt.rcParams["axes.prop_cycle"].by_key()["color"]


def plot_nodes(data: RunData, path) -> Path:
    """Node x, y, z against time (Fig. 7 for the D-bar): estimate solid, truth dashed."""
    est, truth = data.get("nodes"), data.get("truth")
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7.5, 7.5))
    for ax, axis in zip(axes, "xyz", strict=True):
        for node, color in zip(data.nodes, _colors(), strict=False):
            col = f"{node}_{axis}_m"
            if est is not None:
                ax.plot(est["t_s"], est[col], color=color, label=f"{node} estimate")
            if truth is not None:
                ax.plot(
                    truth["t_s"], truth[col], color=color, ls="--", lw=0.9, label=f"{node} truth"
                )
        ax.set_ylabel(f"{axis} (m)")
    axes[0].legend(ncol=4, fontsize="x-small")
    axes[-1].set_xlabel("t (s)")
    fig.suptitle(f"{data.title}: node coordinates" + (" (Fig. 7)" if data.dbar else ""))
    return _finish(fig, axes, data, path)


def plot_node_z(data: RunData, path) -> Path:
    """Node z of the D-bar's plane nodes, estimate and (simulated rig) truth (Fig. 8 on the
    rig)."""
    est, truth = data.get("nodes"), data.get("truth")
    fig, axes = plt.subplots(2, 2, sharex=True, sharey=True, figsize=(8, 5.5))
    for ax, node in zip(axes.ravel(), PLANE_NODES, strict=True):
        col = f"{node}_z_m"
        if est is not None:
            ax.plot(est["t_s"], 100 * est[col], label="estimate (EKF)")
        if truth is not None:
            ax.plot(truth["t_s"], 100 * truth[col], "k--", lw=0.9, label="truth (rig)")
        ax.set_title(node)
        ax.set_ylabel("z (cm)")
    for ax in axes[-1]:
        ax.set_xlabel("t (s)")
    axes[0, 0].legend(fontsize="small")
    compared = "estimate against truth" if data.has_truth else "estimate"
    fig.suptitle(f"{data.title}: node z, {compared} (Fig. 8)")
    return _finish(fig, axes, data, path)


def plot_attitude(data: RunData, path) -> Path:
    """The IMU's roll and pitch (measured, EKF); for the D-bar above them the tilt of its plane
    (estimate, truth)."""
    est, truth, imu = data.get("estimate"), data.get("truth"), data.get("imu")
    nodes = data.get("nodes")
    fig, axes = plt.subplots(
        2 if data.dbar else 1, 1, sharex=True, figsize=(7.5, 5.5 if data.dbar else 3.5)
    )
    axes = np.atleast_1d(axes)
    if data.dbar:
        if nodes is not None:
            axes[0].plot(nodes["t_s"], np.degrees(nodes["tilt_rad"]), label="estimate")
        if truth is not None:
            axes[0].plot(truth["t_s"], np.degrees(truth["tilt_rad"]), "k--", lw=0.9, label="truth")
        axes[0].set_ylabel("plane tilt about n2-n4 (deg)")
        axes[0].legend(fontsize="small")
    if imu is not None:
        for col in ("roll_rad", "pitch_rad"):
            axes[-1].plot(imu["t_s"], np.degrees(imu[col]), lw=0.8, label=f"IMU {col[:-4]}")
    if est is not None:
        for col in ("roll_rad", "pitch_rad"):
            axes[-1].plot(est["t_s"], np.degrees(est[col]), "--", lw=0.8, label=f"EKF {col[:-4]}")
    axes[-1].set_ylabel("angle (deg)")
    axes[-1].set_xlabel("t (s)")
    axes[-1].legend(fontsize="small", ncol=2)
    fig.suptitle(f"{data.title}: attitude")
    return _finish(fig, axes, data, path)


def plot_wheels(data: RunData, path) -> Path:
    """Wheel speeds: commanded (dashed) and measured by the board (solid)."""
    cmd, tel = data.get("command"), data.get("wheels")
    fig, ax = plt.subplots(figsize=(7.5, 4))
    for i, color in zip(range(4), _colors(), strict=False):
        if tel is not None:
            ax.plot(tel["t_s"], tel[f"omega_{i}_rad_s"], color=color, label=f"wheel {i} measured")
        if cmd is not None:
            ax.plot(cmd["t_s"], cmd[f"omega_cmd_{i}_rad_s"], color=color, ls="--", lw=0.9)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("speed (rad/s)")
    ax.legend(fontsize="x-small", ncol=2, title="dashed: commanded", title_fontsize="x-small")
    ax.set_title(f"{data.title}: wheel speeds")
    return _finish(fig, ax, data, path)


def plot_innovations(data: RunData, path) -> Path:
    """NIS test ratio (NIS / gate) per source, log scale; above 1 the sample was rejected."""
    present = [s for s in INNOVATION_SOURCES if data.get(f"innov_{s}") is not None]
    fig, axes = plt.subplots(
        max(len(present), 1), 1, sharex=True, figsize=(7.5, 1.6 + 1.5 * len(present))
    )
    axes = np.atleast_1d(axes)
    for ax, source in zip(axes, present, strict=False):
        s = data.get(f"innov_{source}")
        ok = s["accepted"] > 0.5
        ratio = np.maximum(s["test_ratio"], 1e-6)
        ax.semilogy(s["t_s"][ok], ratio[ok], ".", ms=2, label="accepted")
        ax.semilogy(s["t_s"][~ok], ratio[~ok], "rx", ms=4, label=f"rejected ({np.sum(~ok)})")
        ax.axhline(1.0, color="r", lw=0.8)
        ax.set_ylabel(f"{source}\nNIS/gate")
        ax.legend(fontsize="x-small", loc="lower right")
    axes[-1].set_xlabel("t (s)")
    fig.suptitle(f"{data.title}: innovation test ratios (gate = 1)")
    return _finish(fig, axes, data, path)


def plot_jitter(data: RunData, path) -> Path:
    """Histogram of the host loop's tick periods, ms (log counts)."""
    loop = data.get("loop")
    fig, ax = plt.subplots(figsize=(6.5, 4))
    if loop is not None and len(loop) > 1:
        periods_ms = 1e3 * np.diff(loop["t_s"])
        ax.hist(periods_ms, bins=60, log=True)
        nominal = 1e3 * data.meta.get("settings", {}).get("rate_hz", 100.0) ** -1
        ax.axvline(nominal, color="r", lw=0.8, label=f"nominal {nominal:g} ms")
        ax.legend(fontsize="small")
    ax.set_xlabel("tick period (ms)")
    ax.set_ylabel("ticks")
    ax.set_title(f"{data.title}: host loop periods")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


PLOTS = {
    "fig7-nodes.png": plot_nodes,
    "fig8-node-z.png": plot_node_z,
    "attitude.png": plot_attitude,
    "wheels.png": plot_wheels,
    "innovations.png": plot_innovations,
    "loop-jitter.png": plot_jitter,
}

NEEDS = {
    "fig7-nodes.png": ("nodes", "truth"),
    "fig8-node-z.png": ("nodes", "truth"),
    "attitude.png": ("nodes", "truth", "imu", "estimate"),
    "wheels.png": ("wheels", "command"),
    "innovations.png": tuple(f"innov_{s}" for s in INNOVATION_SOURCES),
    "loop-jitter.png": ("loop",),
}
"""Figure -> the streams it draws; it is made if at least one of them has rows."""


DBAR_ONLY = ("fig8-node-z.png",)
"""Figures of the D-bar's plane nodes, made for D-bar logs only."""


def plots_for(data: RunData) -> dict:
    """The figures (file name -> function) of a log: all of :data:`PLOTS` for a D-bar, all but
    :data:`DBAR_ONLY` for any other scene."""
    return {name: plot for name, plot in PLOTS.items() if data.dbar or name not in DBAR_ONLY}


def plot_log(folder, out, warn: Callable[[str], None] | None = None) -> list[Path]:
    """Write every figure of the log ``folder`` (:func:`plots_for`) that has data into ``out``;
    returns the paths.

    A figure whose streams (:data:`NEEDS`) are all missing or empty is left out, and said so to
    ``warn``; with ``warn`` a damaged stream is read as far as it can be (:class:`RunData`).
    Nothing is created when no figure has data.
    """
    data = RunData(folder, warn)
    made = {}
    for name, plot in plots_for(data).items():
        if any(data.get(s) is not None for s in NEEDS[name]):
            made[name] = plot
        elif warn is not None:
            warn(f"{name} left out: no rows in {data.folder} of {', '.join(NEEDS[name])}")
    if made:
        Path(out).mkdir(parents=True, exist_ok=True)
    return [plot(data, Path(out) / name) for name, plot in made.items()]


def plot_compare(folders, labels, path) -> Path:
    """Node z in several runs side by side (Fig. 7(a) against 7(b) for the D-bar), cm."""
    runs = [RunData(f) for f in folders]
    any_truth = any(data.has_truth for data in runs)
    fig, axes = plt.subplots(1, len(runs), sharey=True, figsize=(5 * len(runs), 4), squeeze=False)
    for ax, data, label in zip(axes[0], runs, labels, strict=True):
        est, truth = data.get("nodes"), data.get("truth")
        for node, color in zip(data.nodes, _colors(), strict=False):
            col = f"{node}_z_m"
            if est is not None:
                ax.plot(est["t_s"], 100 * est[col], color=color, label=f"{node} estimate")
            if truth is not None:
                ax.plot(truth["t_s"], 100 * truth[col], color=color, ls="--", lw=0.9)
        ax.set_title(label)
        ax.set_xlabel("t (s)")
        if data.t_schedule is not None:
            ax.axvline(data.t_schedule, color="0.5", lw=0.8, ls=":")
        ax.grid(True, alpha=0.3)
    axes[0, 0].set_ylabel("node z (cm)")
    axes[0, 0].legend(
        fontsize="x-small", title="dashed: truth" if any_truth else None, title_fontsize="x-small"
    )
    fig.suptitle(
        "node z on the simulated rig: EKF estimate (solid) and truth (dashed)"
        if any_truth
        else "node z: EKF estimate"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return Path(path)
