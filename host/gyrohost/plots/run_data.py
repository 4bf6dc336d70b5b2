"""What the figures of a run log draw, read from its streams: the log itself, the ±2σ bands of
the estimate, the attitude as angles without jumps, the body frame's attitude, the normalised
innovations.

No drawing here, so that tests check the data a figure draws without reading images.
"""

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gyrohost.control.attitude import PLANE_NODES
from gyrohost.geometry import rotation_zyx
from gyrohost.run.health import nis_row
from gyrohost.run.log import read_meta, read_streams
from gyrohost.run.streams import BODY_ATTITUDE

BAND_SIGMAS = 2.0
"""Half width of the estimate's uncertainty band, standard deviations."""
INNOVATION_BAND = 1.959963984540054
"""Two-sided 95 % quantile of the standard normal: the band of a normalised innovation."""


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
        scene_nodes = [
            c[: -len("_x_m")] for c in columns if c.endswith("_x_m") and not c.startswith("std_")
        ]
        self.nodes = PLANE_NODES if self.dbar else tuple(scene_nodes)
        """The nodes the figures show: the D-bar's plane nodes, else every scene node."""
        self.body = BODY_ATTITUDE[0] in columns
        """The log has the attitude of the scene's body frame (its ``[attitude]`` table)."""

    def get(self, name):
        s = self.streams.get(name)
        return s if s is not None and len(s) else None


def band(stream, column, scale=1.0, unwrap=False):
    """The ±2σ band of ``column`` of ``stream`` from its ``std_<column>``, times ``scale``:
    (lower, upper) arrays, or None when the stream has no such column (a log written before
    the estimate logged it). ``unwrap``: about the angle unwrapped over time, as drawn."""
    std = f"std_{column}"
    if std not in stream.dtype.names:
        return None
    value, half = stream[column], BAND_SIGMAS * stream[std]
    if unwrap:
        value = np.unwrap(value)
    return scale * (value - half), scale * (value + half)


def rotations(roll_rad, pitch_rad, yaw_rad):
    """Rotations (K, 3, 3) of Z-Y-X angles (K,) each, rad (sensor axes in the world)."""
    return np.moveaxis(rotation_zyx(roll_rad, pitch_rad, yaw_rad), -1, 0)


def tilt_heading(R):
    """Tilt from the vertical and heading, rad, of sensor axes ``R`` (K, 3, 3) in the world.

    The tilt is the angle of the sensor z axis from the world's z axis (0 to pi). The heading is
    the twist of the swing-twist decomposition about the sensor z axis, ``2 atan2(q_z, q_w)`` of
    the attitude quaternion: the yaw when level, defined at every attitude but upside down
    (tilt pi), unwrapped over time. Unlike Z-Y-X angles, neither jumps at a pitch of -90° nor
    at ±180°.
    """
    heading = np.arctan2(R[:, 1, 0] - R[:, 0, 1], R[:, 0, 0] + R[:, 1, 1])
    return np.arccos(np.clip(R[:, 2, 2], -1.0, 1.0)), np.unwrap(heading)


def euler_tilt_heading(stream):
    """:func:`tilt_heading` of a stream with ``roll_rad, pitch_rad, yaw_rad`` columns."""
    return tilt_heading(rotations(stream["roll_rad"], stream["pitch_rad"], stream["yaw_rad"]))


def sensor_axes(a, b, c, mounting_rpy_rad=(0.0, 0.0, 0.0)):
    """Sensor axes (K, 3, 3) of the IMU attached to nodes at ``a, b, c`` (K, 3), m, as the
    estimator attaches it (:mod:`gyrohost.estimator.imu_model`): x along a -> b, z along x
    cross (c - a), y = z cross x, turned by the mounting angles (Z-Y-X, rad)."""
    ex = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)
    ez = np.cross(ex, c - a)
    ez /= np.linalg.norm(ez, axis=1, keepdims=True)
    R_wb = np.stack([ex, np.cross(ez, ex), ez], axis=2)
    return R_wb @ rotation_zyx(*mounting_rpy_rad)


def truth_axes(data: RunData):
    """The true sensor axes (K, 3, 3) from the ``truth`` stream's nodes, attached as the log's
    estimator configuration says; None without a truth or without the attachment's nodes."""
    truth = data.get("truth")
    est = data.meta.get("estimator", {})
    names = est.get("imu_frame_nodes")
    if truth is None or not names or any(f"{n}_x_m" not in truth.dtype.names for n in names):
        return None
    a, b, c = (np.column_stack([truth[f"{n}_{ax}_m"] for ax in "xyz"]) for n in names)
    return sensor_axes(a, b, c, est.get("imu_mounting_rpy_rad", (0.0, 0.0, 0.0)))


def attitude_lines(data: RunData) -> dict:
    """Sensor tilt from the vertical and unwrapped heading (:func:`.run_data.tilt_heading`),
    rad: label -> (t_s, tilt, heading) for the IMU's own angles, the estimate and the truth's
    sensor axes, those the log has."""
    lines = {}
    imu, est, truth = data.get("imu"), data.get("estimate"), data.get("truth")
    if imu is not None:
        lines["IMU (measured)"] = (imu["t_s"], *euler_tilt_heading(imu))
    if est is not None:
        lines["estimate"] = (est["t_s"], *euler_tilt_heading(est))
    R_true = truth_axes(data)
    if R_true is not None:
        lines["truth"] = (truth["t_s"], *tilt_heading(R_true))
    return lines


@dataclass
class BodyLine:
    """The body frame's attitude in one stream, as :func:`body_lines` draws it."""

    t_s: np.ndarray
    rpy_rad: np.ndarray
    """(K, 3) roll, pitch, yaw, rad, each unwrapped over time"""
    turn_rad: np.ndarray
    """(K,) the rotation angle from the start, rad, in [0, pi]: ``2 acos |w|``"""


def body_lines(data: RunData) -> dict:
    """The body frame's attitude of the estimate (``nodes``) and of the truth, those the log
    has: label -> :class:`BodyLine`."""
    lines = {}
    for label, name in (("estimate", "nodes"), ("truth", "truth")):
        stream = data.get(name)
        if stream is None or BODY_ATTITUDE[0] not in stream.dtype.names:
            continue
        rpy = np.column_stack([stream[c] for c in BODY_ATTITUDE[4:]])
        w = np.clip(np.abs(stream[BODY_ATTITUDE[0]]), 0.0, 1.0)
        lines[label] = BodyLine(stream["t_s"], np.unwrap(rpy, axis=0), 2.0 * np.arccos(w))
    return lines


@dataclass
class Normalised:
    """The innovations of one source, each component divided by its standard deviation."""

    t_s: np.ndarray
    components: dict
    """component name -> (K,) normalised innovation, 1"""
    accepted: np.ndarray
    nis_mean: float
    dof: int
    bounds: tuple
    """95 % chi-square bounds of the mean NIS over ``len(t_s)`` samples (as if independent)"""


def normalised_innovations(stream) -> Normalised:
    """:class:`Normalised` of an ``innov_<source>`` stream (``y_<c>``, ``var_<c>`` columns); the
    mean NIS over every attempt, rejected ones included, as the run's summary gives it
    (:func:`gyrohost.run.health.nis_row`)."""
    names = [c[2:] for c in stream.dtype.names if c.startswith("y_")]
    comps = {c: stream[f"y_{c}"] / np.sqrt(stream[f"var_{c}"]) for c in names}
    row = nis_row(stream["nis"], len(names))
    return Normalised(
        stream["t_s"],
        comps,
        stream["accepted"] > 0.5,
        row["mean"],
        row["dof"],
        tuple(row["bounds95"]),
    )
