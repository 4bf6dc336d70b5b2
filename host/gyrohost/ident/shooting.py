"""Multiple shooting: a recording cut into segments, each simulated from its own start state.

The D-bar has an unstable roll mode: a prediction simulated from the start of a long recording
follows it only until a small mismatch has grown into a roll the rig never made. Cut into
segments of ``segment_s`` (:func:`segment_starts`), the first one starts where the rig starts
(the scene's initial state, exactly known), every later one from the previous one's end
turned to the IMU's tilt and rate at its start (:func:`anchored`), or, if asked, from the
host estimator's logged state there (:func:`start_states`; far off while the estimator runs a
scene not yet identified). The parameters are shared across segments; the start states are
held, not fitted, and segments the prediction does not follow are left out
(:func:`predictable`); reports/identification-history.md, "Why the starts are held", has the
measurements behind both.
"""

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from gyrohost.geometry import levelling_rotvec
from gyrotensegrity.projection import project

FIRST_PASS_S = 4.0
"""The first pass of the fit (:func:`.fit.fit`) takes at least this much of each recording, s:
2 s held so little of the pulls that the strings' stiffness wandered to where the model's
fixed step is unstable."""
UNPREDICTABLE = 2.0
"""A segment whose weighted residual RMS after the first pass exceeds this many times the first
segment's is left out of the fit (:func:`predictable`). Followed segments are within 1.2 times
the first's, those past a fold 4.8 times and more (reports/identification-history.md, "Several
recordings"): a fold's first segment, kept, drags the strings by tens of percent."""
ANCHOR_HALF_S = 0.05
"""IMU samples within this of a segment's start are averaged into its anchor, s."""


def segment_starts(n_steps: int, dt_s: float, segment_s: float) -> np.ndarray:
    """Step indices where segments start, shape (k,): 0 first, every ``segment_s`` (rounded
    to a step) after; a single segment for ``segment_s <= 0``. A last piece shorter than half
    a segment joins the one before."""
    if segment_s <= 0.0:
        return np.zeros(1, int)
    every = max(int(round(segment_s / dt_s)), 1)
    starts = np.arange(0, n_steps, every)
    if len(starts) > 1 and n_steps - starts[-1] < every // 2:
        starts = starts[:-1]
    return starts


def start_states(model, t_starts_s, t_estimate_s, estimate_x) -> list:
    """The state each segment starts from: ``None`` (the first: the scene's initial state; a
    later one without an estimate there: the previous segment's end), else the estimator's
    positions and velocities interpolated to the start, the wheel angles zero, projected onto
    the bars' lengths and the rates that keep them.

    Parameters
    ----------
    model : gyrotensegrity.Model
        The simulated model (its state layout; the estimate's reduced coordinates are its
        ``q`` and ``q_dot``).
    t_starts_s : ndarray, shape (k,), s
    t_estimate_s : ndarray, shape (ke,), s
        The estimate's times (the recording's clock).
    estimate_x : ndarray, shape (ke, 6 m)
        ``q`` then ``q_dot`` at those times, m and m/s.
    """
    L = model.layout
    out = [None]
    for t in t_starts_s[1:]:
        if not len(t_estimate_s) or not t_estimate_s[0] <= t <= t_estimate_s[-1]:
            out.append(None)
            continue
        x = np.zeros(L.size)
        x[: 6 * L.m] = [np.interp(t, t_estimate_s, v) for v in estimate_x.T]
        out.append(project(model, x))
    return out


def anchored(truth, x, t_imu_s, imu, t_s: float, R_bs, gyro_bias_rad_s):
    """The state ``x`` (a segment's predicted end) turned rigidly so that the sensor's tilt
    is the IMU's at ``t_s`` (its yaw kept: the smallest rotation that does it), and given the
    rigid rotation that makes the sensor's rate the IMU's (both averaged over
    :data:`ANCHOR_HALF_S` either side, :func:`mean_up`), projected onto the bars' lengths;
    ``x`` itself without samples there.

    ``R_bs`` (3, 3): the sensor's axes in the IMU frame, ``gyro_bias_rad_s`` (3,): what turns
    the IMU's readings into the frame's attitude and rate (the fit's first pass,
    :func:`.fit.fit`).

    The D-bar's motion does not depend on where it points (its scenes have no gravity), so
    turning the whole state leaves the dynamics alone: only the drift of the unstable roll
    mode, in attitude and rate, is reset to what the IMU sees; the shape and its vibration
    continue from the previous segment.
    """
    win = np.abs(t_imu_s - t_s) <= ANCHOR_HALF_S
    if not np.any(win):
        return x
    model, L = truth.model, truth.model.layout
    N, N_dot = model.nodes(x)
    omega, _, R = truth.frame_motion(N[..., None], N_dot[..., None], np.zeros_like(N)[..., None])
    # the IMU's up direction in the predicted world, levelled by a turn about a horizontal axis
    Q = Rotation.from_rotvec(levelling_rotvec(R[0] @ R_bs @ mean_up(imu[win, 6:8]))).as_matrix()
    q = Q @ x[L.q].reshape(3, L.m)
    rate = R_bs @ (np.mean(imu[win, :3], axis=0) - gyro_bias_rad_s)
    d_omega = Q @ R[0] @ (rate - omega[0])
    q_dot = Q @ x[L.q_dot].reshape(3, L.m) + np.cross(d_omega, q.T).T
    out = x.copy()
    out[L.q], out[L.q_dot] = q.ravel(), q_dot.ravel()
    return project(model, out)


def mean_up(roll_pitch_rad) -> np.ndarray:
    """The mean up direction, sensor axes, shape (3,), of attitudes given by their roll and
    pitch (k, 2), rad: the unit mean of each one's (the attitude's third row; its yaw does not
    enter): the tilt averaged as a direction. Not the angles' mean: near pitch -90 degrees roll
    jumps by up to pi between samples, and pitch, which never passes -90, is biased above it."""
    roll, pitch = roll_pitch_rad[:, 0], roll_pitch_rad[:, 1]
    up = np.column_stack(
        [-np.sin(pitch), np.cos(pitch) * np.sin(roll), np.cos(pitch) * np.cos(roll)]
    )
    mean = up.mean(axis=0)
    return mean / np.linalg.norm(mean)


def edges_s(rec, dt_s: float) -> np.ndarray:
    """Start times of the segments of ``rec`` and the end of its last, shape (k + 1,), s (the
    segmenting of :func:`.forward.simulate`)."""
    n = int(np.ceil(rec.t_imu_s[-1] / dt_s)) + 1
    return np.append(dt_s * segment_starts(n, dt_s, rec.segment_s), np.inf)


def predictable(rec, weighted_errors, dt_s: float):
    """``rec`` without the IMU samples of the segments its prediction does not follow: their
    weighted residual RMS (``weighted_errors``, shape (k, 8), at the first pass's optimum)
    above :data:`UNPREDICTABLE` times the first segment's. Past the point where the D-bar rolls
    over, a segment's prediction can leave the recording within a fraction of a second from any
    start the IMU fixes (docs/identification.md); fitted, such segments drag every parameter.

    Returns
    -------
    rec : Recording
    dropped : list of (float, float)
        The windows left out, s.
    """
    edges = edges_s(rec, dt_s)
    seg = np.searchsorted(edges, rec.t_imu_s, "right") - 1
    rms = np.array(
        [np.sqrt(np.mean(weighted_errors[seg == i] ** 2)) for i in range(len(edges) - 1)]
    )
    bad = np.flatnonzero(rms > UNPREDICTABLE * rms[0])
    keep = ~np.isin(seg, bad)
    last = rec.t_imu_s[-1]
    dropped = [(float(edges[i]), float(min(edges[i + 1], last))) for i in bad]
    return replace(rec, t_imu_s=rec.t_imu_s[keep], imu=rec.imu[keep]), dropped
