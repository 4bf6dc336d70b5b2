"""Run logs (docs/run.md) as :class:`.forward.Recording`: the part of the run where the rig
starts from the scene's initial state with its wheels spun up (from the ``lead_in`` phase) up to
the safe state (the ``rampdown`` phase), else the whole log."""

from dataclasses import replace
from pathlib import Path

import numpy as np

from gyrohost.config import RigConfig
from gyrohost.estimator import streams
from gyrohost.estimator.config import for_rig
from gyrohost.estimator.sample_feed import regular_times, wheel_times
from gyrohost.ident.errors import IdentDataError
from gyrohost.ident.forward import Recording, recording
from gyrohost.run.errors import LogError
from gyrohost.run.log import read_meta, read_stream
from gyrohost.run.log_screen import LogScreen
from gyrohost.run.replay import FUSED, LATER
from gyrohost.run.summary import real_time_lost

FIRST_PHASE, LAST_PHASE = "lead_in", "rampdown"
MAX_BAD_SHARE = 0.01
"""Largest share of a fused stream's rows that may be left out (:mod:`gyrohost.run.log_screen`)
for a log to be identified from. The rows left out are few and scattered in a log a power loss
or a stray edit damaged, and the fit loses little with them; more points at a recording gone
wrong as a whole (a disk failing, a stream written twice, a link delivering garbage), whose
other rows are no longer to be trusted either."""


def phase_starts(events: np.ndarray) -> dict[str, float]:
    """Phase -> host time (s) it first begins, from a log's ``events`` rows."""
    times = {}
    for row in events:
        if row["kind"] == "phase":
            times.setdefault(str(row["message"]), float(row["t_s"]))
    return times


def log_warnings(folder: Path) -> list[str]:
    """What makes the log ``folder`` a doubtful recording to identify from: a run that ended
    before its schedule did (how far the schedule got), or a simulated rig whose truth did not
    keep real time."""
    try:
        summary = read_meta(folder).get("summary")
    except LogError:
        return []  # the recording's own loading names what is missing
    if summary is None:
        return [f"{folder}: the run has no summary (it never reached its safe state)"]
    out = []
    if not summary.get("completed", False):
        out.append(f"{folder}: the run stopped {_how_far(folder)} ({summary.get('reason')})")
    lost = real_time_lost(summary)
    if lost:
        out.append(f"{folder}: {lost}")
    return out


def _how_far(folder: Path) -> str:
    """How far into its schedule the run of the log ``folder`` got: from the ``schedule``
    phase's start to the ``end`` event."""
    try:
        events = read_stream(folder, "events")
    except LogError:
        return "at an unknown time (no events)"
    start = phase_starts(events).get("schedule")
    if start is None:
        return "before its schedule began"
    ends = [float(row["t_s"]) for row in events if row["kind"] == "end"]
    return f"{ends[0] - start:.1f} s into its schedule" if ends else "in its schedule"


def phase_window(folder: Path) -> tuple[float | None, float | None]:
    """Host times (s) where ``lead_in`` and ``rampdown`` begin (``None`` if not logged)."""
    try:
        times = phase_starts(read_stream(folder, "events"))
    except LogError:
        return None, None
    return times.get(FIRST_PHASE), times.get(LAST_PHASE)


def windowed(folder: Path, data: dict, until_s: float | None = None):
    """The streams ``data`` (name -> rows with host times ``t_s``, an ``imu`` among them) of
    the log folder ``folder`` within its phases (:func:`phase_window`), at most ``until_s``
    from the start (of ``lead_in``, else of the IMU): every stream cut at the end, and every
    stream but the IMU from its last row before the start (commands and reports logged then
    hold over it); the IMU whole before the end. Returns (the streams, the start or None)."""
    start, end = phase_window(folder)
    if until_s is not None:
        first = start if start is not None else float(data[streams.IMU]["t_s"][0])
        end = first + until_s if end is None else min(end, first + until_s)
    if end is not None:
        data = {k: v[v["t_s"] < end] for k, v in data.items()}
    if start is not None:
        data = {
            k: v if k == streams.IMU else v[max(np.searchsorted(v["t_s"], start) - 1, 0) :]
            for k, v in data.items()
        }
    return data, start


def load_recording(
    folder,
    config: RigConfig,
    n_wheels: int,
    commanded=False,
    until_s=None,
    segment_s=0.0,
    segment_start="imu",
    warn=None,
) -> Recording:
    """The :class:`Recording` of the log folder ``folder``; with ``until_s``, only its first
    ``until_s`` seconds (from the start of ``lead_in``, else of the log); simulated in
    segments of ``segment_s`` (0: one), a later one started as ``segment_start`` says
    (:class:`.forward.Recording`; the ``estimate`` stream read where logged). Rows not to be
    fused are left out (:func:`read_fused`).

    Raises
    ------
    IdentDataError
        A stream is missing or unreadable, too many of its rows are left out, or the window is
        shorter than two IMU samples.
    """
    folder = Path(folder)
    data = read_fused(folder, warn)
    est = for_rig(config)
    if streams.IMU in data:
        # sampled on the IMU's grid, arrival-stamped in bursts: the grid back, as the run loop
        # and gyrotens replay fuse them (estimator.driver.RegularClock)
        imu = data[streams.IMU].copy()
        imu["t_s"] = regular_times(imu["t_s"], est.imu_period_s, est.imu_max_delay_s)
        data[streams.IMU] = imu
    if streams.WHEELS in data:  # on the board's clock, as the run loop and replay take them
        wheels = data[streams.WHEELS].copy()
        wheels["t_s"] = wheel_times(wheels, est)
        data[streams.WHEELS] = wheels
    data, start = windowed(folder, data, until_s)
    rec = recording(str(folder), data, config, n_wheels, start, commanded)
    t_est, est_x = _estimate(folder, float(data[streams.IMU]["t_s"][0]) if start is None else start)
    return replace(
        rec,
        segment_s=float(segment_s),
        segment_start=segment_start,
        t_estimate_s=t_est,
        estimate_x=est_x,
    )


def _estimate(folder: Path, t0_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The ``estimate`` stream's times (from ``t0_s``) and reduced coordinates with their rates
    (columns ``q_*`` then ``qdot_*``, in the filter's order), shapes (ke,) and (ke, 6 m); empty
    without the stream."""
    try:
        est = read_stream(folder, streams.ESTIMATE)
    except LogError:
        return np.zeros(0), np.zeros((0, 0))
    names = est.dtype.names
    cols = [c for c in names if c.startswith("q_")] + [c for c in names if c.startswith("qdot_")]
    return est["t_s"] - t0_s, np.column_stack([est[c] for c in cols])


def read_fused(folder: Path, warn=None, every: bool = True) -> dict:
    """The streams of the log ``folder`` the filter fuses (all of them, or with ``every``
    false those it has), by name; rows not to be fused left out (:mod:`gyrohost.run.log_screen`),
    each kind told to ``warn`` (without it, a row that cannot be read is an error).

    Raises
    ------
    IdentDataError
        A stream is missing (with ``every``) or cannot be read, or more than
        :data:`MAX_BAD_SHARE` of its rows were left out (:func:`refuse_damaged`).
    """
    screen = LogScreen(FUSED)
    try:
        logged = read_meta(folder)["streams"]
        names = [n for n in FUSED if (every and n not in LATER) or n in logged]
        data = {name: read_stream(folder, name, warn, screen) for name in names}
    except LogError as exc:
        raise IdentDataError(str(exc)) from None
    refuse_damaged(screen)
    return data


def refuse_damaged(screen: LogScreen) -> None:
    """Refuse a log of which more than :data:`MAX_BAD_SHARE` of a fused stream's rows were left
    out by ``screen``, naming the stream, the kinds and the rows.

    Raises
    ------
    IdentDataError
    """
    for s in screen.screens.values():
        if s.bad > MAX_BAD_SHARE * s.rows:
            kinds = ", ".join(f"{n} {k.replace('_', '-')}" for k, n in s.counts().items()
                              if k != "rows" and n)  # fmt: skip
            raise IdentDataError(
                f"{s.path}: {s.bad} of {s.rows} rows cannot be fused ({kinds}: "
                f"{s.bad_rows_text()}), more than the {100 * MAX_BAD_SHARE:g} % identify "
                "accepts: record the run again"
            )
