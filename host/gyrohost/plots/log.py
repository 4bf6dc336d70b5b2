"""Figures of a run log (``gyrotens plot LOGDIR``): the paper's Figs. 7 and 8 and diagnostics.

Every figure has time on the host clock of the run (``t_s``, s) and marks where the schedule
started. Estimates are drawn with their ±2σ band where the log has the standard deviations
(``std_`` columns; an older log gets the lines alone and a note saying so), truth lines
(simulated rig only) thin and dashed in the same colour. Lines that can lie on top of each other
(nodes, wheels) differ in dash pattern and marker as well as colour. A log without a truth (a
separate rig process, real hardware) is titled "estimate" only.

The figures follow the scene, as the log holds it: a D-bar log (its ``nodes`` stream has a
``tilt_rad`` column) gets the paper's figures of the plane nodes and the tilt; any other scene
gets every node's coordinates, the IMU's attitude, wheels, innovations and loop timing
(:func:`plots_for`); a log of a scene with a body frame (``[attitude]``) also the frame's roll,
pitch, yaw and turn from the start. A figure whose streams are all missing or empty (a replay's
log, a damaged log) is left out and said so: no figure is written empty. Each ``figure_*``
function returns the figure unsaved (what the tests inspect); :func:`plot_log` saves them. What
they draw is computed in :mod:`.run_data`.
"""

from collections.abc import Callable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gyrohost.control.attitude import PLANE_NODES  # noqa: E402
from gyrohost.plots.run_data import (  # noqa: E402
    INNOVATION_BAND,
    RunData,
    attitude_lines,
    band,
    body_lines,
    normalised_innovations,
)
from gyrohost.plots.styles import MARKERS, style  # noqa: E402

INNOVATION_SOURCES = ("imu_rate", "imu_accel", "imu_angle", "wheels", "servos")
DPI = 110
NO_BAND = "no ±2σ band: this log has no std_ columns (written before they were logged)"


def _band(ax, stream, column, color, scale=1.0, unwrap=False) -> bool:
    """Fill the ±2σ band of ``column`` (:func:`band`); False when the log has none."""
    limits = band(stream, column, scale, unwrap)
    if limits is not None:
        ax.fill_between(stream["t_s"], *limits, color=color, alpha=0.2, lw=0)
    return limits is not None


def _note(fig, drawn_all: bool, est) -> None:
    if est is not None and not drawn_all:
        fig.text(0.01, 0.005, NO_BAND, fontsize="x-small", color="0.3")


def _finish(fig, axes, data):
    for ax in np.ravel(axes):
        if data.t_schedule is not None:
            ax.axvline(data.t_schedule, color="0.5", lw=0.8, ls=":")
        ax.grid(True, alpha=0.3)
    fig.tight_layout(rect=(0, 0.02, 1, 1))
    return fig


def save(fig, path) -> Path:
    """Write ``fig`` to ``path`` (PNG) and close it."""
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return Path(path)


def _node_lines(ax, data, axis, scale=1.0) -> bool:
    """Every node's coordinate ``axis`` (estimate, band, truth) on ``ax``; False when a band is
    missing."""
    est, truth = data.get("nodes"), data.get("truth")
    banded = True
    for i, node in enumerate(data.nodes):
        col = f"{node}_{axis}_m"
        if est is not None:
            st = style(i, len(est))
            banded &= _band(ax, est, col, st["color"], scale)
            ax.plot(est["t_s"], scale * est[col], label=f"{node} estimate", **st)
        if truth is not None:
            st = style(i, len(truth), truth=True)
            ax.plot(truth["t_s"], scale * truth[col], label=f"{node} truth", **st)
    return banded


def figure_nodes(data: RunData):
    """Node x, y, z against time (Fig. 7 for the D-bar): estimate with its ±2σ band, truth
    dashed."""
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(9, 7.5))
    banded = all([_node_lines(ax, data, axis) for ax, axis in zip(axes, "xyz", strict=True)])
    for ax, axis in zip(axes, "xyz", strict=True):
        ax.set_ylabel(f"{axis} (m)")
    axes[0].legend(fontsize="x-small", title="shaded: estimate ±2σ", title_fontsize="x-small",
                   loc="upper left", bbox_to_anchor=(1.01, 1.0))  # fmt: skip
    axes[-1].set_xlabel("t (s)")
    fig.suptitle(f"{data.title}: node coordinates" + (" (Fig. 7)" if data.dbar else ""))
    _note(fig, banded, data.get("nodes"))
    return _finish(fig, axes, data)


def figure_node_z(data: RunData):
    """Node z of the D-bar's plane nodes, estimate with its ±2σ band and (simulated rig)
    truth, cm (Fig. 8 on the rig)."""
    est, truth = data.get("nodes"), data.get("truth")
    fig, axes = plt.subplots(2, 2, sharex=True, sharey=True, figsize=(8, 5.5))
    banded = True
    for ax, node in zip(axes.ravel(), PLANE_NODES, strict=True):
        col = f"{node}_z_m"
        if est is not None:
            has_band = _band(ax, est, col, "C0", 100.0)
            banded &= has_band
            label = "estimate (EKF) ±2σ" if has_band else "estimate (EKF)"
            ax.plot(est["t_s"], 100 * est[col], label=label)
        if truth is not None:
            ax.plot(truth["t_s"], 100 * truth[col], "k--", lw=0.9, label="truth (rig)")
        ax.set_title(node)
        ax.set_ylabel("z (cm)")
    for ax in axes[-1]:
        ax.set_xlabel("t (s)")
    axes[0, 0].legend(fontsize="small")
    compared = "estimate against truth" if data.has_truth else "estimate"
    fig.suptitle(f"{data.title}: node z, {compared} (Fig. 8)")
    _note(fig, banded, est)
    return _finish(fig, axes, data)


def _plane_tilt(ax, data) -> bool:
    nodes, truth = data.get("nodes"), data.get("truth")
    banded = True
    if nodes is not None:
        banded = _band(ax, nodes, "tilt_rad", "C0", np.degrees(1.0), unwrap=True)
        label = "estimate ±2σ" if banded else "estimate"
        ax.plot(nodes["t_s"], np.degrees(np.unwrap(nodes["tilt_rad"])), label=label)
    if truth is not None:
        ax.plot(truth["t_s"], np.degrees(np.unwrap(truth["tilt_rad"])), "k--", lw=0.9,
                label="truth")  # fmt: skip
    ax.set_ylabel("plane tilt about\nn2-n4 (deg)")
    ax.legend(fontsize="small")
    return banded


ATTITUDE_STYLES = {
    "IMU (measured)": {"color": "0.6", "lw": 1.6},
    "estimate": {"color": "C0", "lw": 1.0},
    "truth": {"color": "k", "ls": "--", "lw": 0.9},
}


def figure_attitude(data: RunData):
    """For the D-bar the tilt of its plane (estimate ±2σ, truth); the sensor's tilt from the
    vertical and its heading (quaternion-derived, unwrapped: no jumps at ±180° nor at a pitch
    of -90°), measured, estimated and true."""
    n = 3 if data.dbar else 2
    fig, axes = plt.subplots(n, 1, sharex=True, figsize=(7.5, 2.2 + 1.9 * n))
    banded = _plane_tilt(axes[0], data) if data.dbar else True
    lines = attitude_lines(data)
    for label, (t, tilt, heading) in lines.items():
        axes[-2].plot(t, np.degrees(tilt), label=label, **ATTITUDE_STYLES[label])
        axes[-1].plot(t, np.degrees(heading), label=label, **ATTITUDE_STYLES[label])
    axes[-2].set_ylabel("sensor z from\nvertical (deg)")
    axes[-1].set_ylabel("heading: twist about\nsensor z (deg)")
    if lines:
        axes[-2].legend(fontsize="small", ncol=3)
    axes[-1].set_xlabel("t (s)")
    fig.suptitle(f"{data.title}: attitude")
    if data.dbar:
        _note(fig, banded, data.get("nodes"))
    return _finish(fig, axes, data)


def figure_body_attitude(data: RunData):
    """The scene's body frame (``[attitude]``): roll, pitch, yaw (intrinsic Z-Y-X about the
    frame's start axes, unwrapped) and the rotation angle from the start, deg; estimate, truth
    dashed."""
    fig, axes = plt.subplots(4, 1, sharex=True, figsize=(7.5, 8.5))
    lines = body_lines(data)
    for label, line in lines.items():
        kw = ATTITUDE_STYLES[label]
        for k, ax in enumerate(axes[:3]):
            ax.plot(line.t_s, np.degrees(line.rpy_rad[:, k]), label=label, **kw)
        axes[3].plot(line.t_s, np.degrees(line.turn_rad), label=label, **kw)
    for ax, what in zip(axes, ("roll", "pitch", "yaw", "turn from\nthe start"), strict=True):
        ax.set_ylabel(f"{what} (deg)")
    if lines:
        axes[0].legend(fontsize="small", ncol=2)
    axes[-1].set_xlabel("t (s)")
    fig.suptitle(f"{data.title}: body frame attitude")
    return _finish(fig, axes, data)


def figure_wheels(data: RunData):
    """Wheel speeds: measured by the board (a dash pattern and marker per wheel), commanded
    (thin dotted)."""
    cmd, tel = data.get("command"), data.get("wheels")
    fig, ax = plt.subplots(figsize=(7.5, 4))
    for i in range(4):
        if tel is not None:
            st = style(i, len(tel))
            ax.plot(tel["t_s"], tel[f"omega_{i}_rad_s"], label=f"wheel {i} measured", **st)
        if cmd is not None:
            ax.plot(cmd["t_s"], cmd[f"omega_cmd_{i}_rad_s"], color=style(i, 0)["color"],
                    ls=":", lw=0.9)  # fmt: skip
    ax.set_xlabel("t (s)")
    ax.set_ylabel("speed (rad/s)")
    ax.legend(fontsize="x-small", ncol=2, title="dotted: commanded", title_fontsize="x-small")
    ax.set_title(f"{data.title}: wheel speeds")
    return _finish(fig, ax, data)


def figure_innovations(data: RunData):
    """Innovations per source, each component divided by its standard deviation (sqrt of the
    diagonal of S): inside ±1.96 95 % of the time when the filter is consistent; the source's
    mean NIS and its 95 % bounds in the legend; rejected samples as crosses."""
    present = [s for s in INNOVATION_SOURCES if data.get(f"innov_{s}") is not None]
    fig, axes = plt.subplots(
        max(len(present), 1), 1, sharex=True, figsize=(9.5, 1.6 + 1.7 * len(present))
    )
    axes = np.atleast_1d(axes)
    for ax, source in zip(axes, present, strict=False):
        inn = normalised_innovations(data.get(f"innov_{source}"))
        ax.axhspan(-INNOVATION_BAND, INNOVATION_BAND, color="0.85", label="95 % (±1.96)")
        for i, (comp, values) in enumerate(inn.components.items()):
            ax.plot(inn.t_s[inn.accepted], values[inn.accepted], MARKERS[i % len(MARKERS)],
                    ms=2, alpha=0.7, label=comp)  # fmt: skip
        rejected = ~inn.accepted
        for values in inn.components.values():
            ax.plot(inn.t_s[rejected], values[rejected], "rx", ms=4)
        lo, hi = inn.bounds
        ax.set_ylabel(f"{source}\ny / sqrt(S)")
        ax.legend(
            fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0),
            title=f"mean NIS {inn.nis_mean:.2f} (dof {inn.dof})\n95 % [{lo:.2f}, {hi:.2f}]\n"
            f"{len(inn.t_s)} samples\n{int(np.sum(rejected))} rejected (red x)",
            title_fontsize="x-small",
        )  # fmt: skip
    axes[-1].set_xlabel("t (s)")
    fig.suptitle(f"{data.title}: normalised innovations")
    return _finish(fig, axes, data)


def figure_jitter(data: RunData):
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
    return fig


def plot_node_z(data: RunData, path) -> Path:
    """:func:`figure_node_z` written to ``path``."""
    return save(figure_node_z(data), path)


PLOTS = {
    "fig7-nodes.png": figure_nodes,
    "fig8-node-z.png": figure_node_z,
    "attitude.png": figure_attitude,
    "body-attitude.png": figure_body_attitude,
    "wheels.png": figure_wheels,
    "innovations.png": figure_innovations,
    "loop-jitter.png": figure_jitter,
}

NEEDS = {
    "fig7-nodes.png": ("nodes", "truth"),
    "fig8-node-z.png": ("nodes", "truth"),
    "attitude.png": ("nodes", "truth", "imu", "estimate"),
    "body-attitude.png": ("nodes", "truth"),
    "wheels.png": ("wheels", "command"),
    "innovations.png": tuple(f"innov_{s}" for s in INNOVATION_SOURCES),
    "loop-jitter.png": ("loop",),
}
"""Figure -> the streams it draws; it is made if at least one of them has rows."""


DBAR_ONLY = ("fig8-node-z.png",)
"""Figures of the D-bar's plane nodes, made for D-bar logs only."""
BODY_ONLY = ("body-attitude.png",)
"""Figures of a body frame's attitude, made for logs that have it only."""


def plots_for(data: RunData) -> dict:
    """The figures (file name -> function) of a log: :data:`PLOTS` but :data:`DBAR_ONLY` for a
    scene other than the D-bar and :data:`BODY_ONLY` for a scene without a body frame."""
    return {
        name: fig
        for name, fig in PLOTS.items()
        if (data.dbar or name not in DBAR_ONLY) and (data.body or name not in BODY_ONLY)
    }


def plot_log(folder, out, warn: Callable[[str], None] | None = None) -> list[Path]:
    """Write every figure of the log ``folder`` (:func:`plots_for`) that has data into ``out``;
    returns the paths.

    A figure whose streams (:data:`NEEDS`) are all missing or empty is left out, and said so to
    ``warn``; with ``warn`` a damaged stream is read as far as it can be (:class:`RunData`).
    Nothing is created when no figure has data.
    """
    data = RunData(folder, warn)
    made = {}
    for name, figure in plots_for(data).items():
        if any(data.get(s) is not None for s in NEEDS[name]):
            made[name] = figure
        elif warn is not None:
            warn(f"{name} left out: no rows in {data.folder} of {', '.join(NEEDS[name])}")
    if made:
        Path(out).mkdir(parents=True, exist_ok=True)
    return [save(figure(data), Path(out) / name) for name, figure in made.items()]


def plot_compare(folders, labels, path) -> Path:
    """Node z in several runs side by side (Fig. 7(a) against 7(b) for the D-bar), cm,
    estimates with their ±2σ bands."""
    runs = [RunData(f) for f in folders]
    any_truth = any(data.has_truth for data in runs)
    fig, axes = plt.subplots(1, len(runs), sharey=True, figsize=(5 * len(runs), 4), squeeze=False)
    banded = True
    for ax, data, label in zip(axes[0], runs, labels, strict=True):
        banded &= _node_lines(ax, data, "z", 100.0)
        ax.set_title(label)
        ax.set_xlabel("t (s)")
        _finish(fig, ax, data)
    axes[0, 0].set_ylabel("node z (cm)")
    axes[0, 0].legend(fontsize="x-small", title="shaded: estimate ±2σ", title_fontsize="x-small")
    fig.suptitle(
        "node z on the simulated rig: EKF estimate and truth (dashed)"
        if any_truth
        else "node z: EKF estimate"
    )
    _note(fig, banded, runs[0].get("nodes"))
    fig.tight_layout(rect=(0, 0.02, 1, 1))
    return save(fig, path)
