"""Rerun the estimator over a run log and write its estimates and innovations to a new log.

Input: a log folder (``gyrohost.run.log``) with the streams of :mod:`.streams` (``imu``,
``wheels``, ``servos``, ``command``; any but ``imu`` may be missing). A damaged log is taken as a
power loss or a bad disk leaves it: a row that cannot be read is skipped, a stream whose file is
missing or empty is left out, each with a warning naming the file, row and column (to the
caller's ``warn`` and into ``summary.warnings`` of the output). Rows of the fused streams that
read but are no samples (a value not finite, time running backwards, a repeated row) are left
out, counted per stream in ``summary.log_rows`` and warned about per kind; so is a stream whose
header is not its declared columns (:mod:`.log_screen`). The scene comes from ``scene`` in
``meta.json`` (a path, relative to the log folder or the working directory) unless given; the
estimator configuration from ``estimator`` in ``meta.json`` (a table of :mod:`.config` keys)
unless given.

The filter covers the span the run's estimator covered (its ``estimate`` rows) and starts with
the wheel speeds, servo lengths and command last logged before it (as the run loop does).

Output: a new log folder with the streams ``estimate`` and ``innov_<source>`` (columns in
:mod:`.streams`) and a ``meta.json`` whose creation time is the input's, so that two replays of
one log are identical byte for byte. Its summary compares the replay's estimate with the run's
own (the input's ``estimate`` stream): the largest difference per group of the filter state
(:data:`GROUPS`) at the run's estimate rows. A log of the simulated rig holds its truth
(``truth``): the summary then scores the replay against it as the run scores its own estimate
(``nees``, :class:`gyrohost.run.health.TruthScore`), so that another scene or estimator
configuration is judged on the same recorded run, whatever the machine's load was.
"""

from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

import numpy as np

from gyrohost.estimator import sample_feed, streams
from gyrohost.estimator.config import EstimatorConfig, config_from_dict
from gyrohost.estimator.ekf import SOURCES, TensegrityEKF
from gyrohost.estimator.errors import EstimatorConfigError
from gyrohost.estimator.imu_model import tilt
from gyrohost.estimator.layout import from_model_state, layout_of
from gyrohost.run.errors import LogError
from gyrohost.run.health import TruthScore
from gyrohost.run.log import RunLog, check_new_log_folder, read_meta, read_stream, read_streams
from gyrohost.run.log_screen import LogScreen
from gyrohost.run.streams import INNOVATION_COMPONENTS, node_columns_of
from gyrotensegrity import Model, load_scene

GROUPS = {
    "nodes_m": "q",
    "velocities_m_s": "q_dot",
    "wheels_rad_s": "omega",
    "rest_lengths_m": "rest",
    "gyro_bias_rad_s": "bias",
}
"""Group of the filter state in the comparison with the run's estimate -> its slice of
:class:`~gyrohost.estimator.layout.FilterLayout`."""


def _scene_path(log: Path, meta: dict) -> Path:
    scene = meta.get("scene")
    if isinstance(scene, dict):
        scene = scene.get("path")
    if not isinstance(scene, str):
        raise EstimatorConfigError(f"{log}/meta.json names no scene path; give the scene")
    for base in (log, Path.cwd()):
        if (base / scene).is_file():
            return base / scene
    raise EstimatorConfigError(f"{log}/meta.json: scene {scene!r} not found")


def _components(source, model):
    if source in INNOVATION_COMPONENTS:
        return INNOVATION_COMPONENTS[source]
    if source == "wheels":
        return tuple(f"w{k}" for k in range(len(model.wheel_bars)))
    return tuple(s.name for s in model.scene.strings)


class _Writer:
    """Writes the estimate after every step and every innovation as it comes."""

    def __init__(self, out: RunLog, ekf, truth=None):
        self.ekf, self.truth = ekf, truth
        self.times, self.states = [], []
        self.estimate = out.stream(
            streams.ESTIMATE,
            streams.estimate_columns(ekf.layout.labels()),
            description="EKF estimate after every sample and prediction step",
        )
        self.innov = {}
        for source in SOURCES:
            comps = _components(source, ekf.model)
            self.innov[source] = (
                out.stream(
                    streams.innovation_stream(source),
                    streams.innovation_columns(comps),
                    description=f"innovations of {source}",
                ),
                len(comps),
            )

    def innovation(self, r):
        stream, k = self.innov[r.source]
        y = np.full(k, np.nan)
        var = np.full(k, np.nan)
        y[: len(r.innovation)], var[: len(r.variance)] = r.innovation, r.variance
        stream.write(r.t_s, *y, *var, r.nis, r.test_ratio, r.accepted, r.rejected_count)

    def step(self, ekf, _stream):
        R, euler = ekf.attitude()
        std = np.sqrt(np.clip(np.diag(ekf.P), 0.0, None))
        self.estimate.write(ekf.t, int(ekf.status), *ekf.x, *std, *euler, tilt(R))
        self.times.append(ekf.t)
        self.states.append(ekf.x.copy())
        if self.truth is not None:
            self.truth.step()


class _Truth:
    """The simulated rig's truth samples of a log, handed to a :class:`TruthScore` as the
    replay's estimate reaches them: each estimate is scored against the truth at its time."""

    def __init__(self, ekf, rows: np.ndarray):
        scene = ekf.model.scene
        self.score = TruthScore(ekf)
        self.t_s = rows["t_s"]
        nodes = [rows[c] for c in node_columns_of(scene.node_names)]
        self.N = np.reshape(np.column_stack(nodes), (len(rows), -1, 3)).transpose(0, 2, 1)
        n_w = layout_of(ekf.model).n_wheels
        self.omega = np.column_stack([rows[f"omega_{i}_rad_s"] for i in range(n_w)])
        self.rest = np.column_stack([rows[streams.rest_column(s.name)] for s in scene.strings])
        self.next = 0

    @classmethod
    def of(cls, log: Path, ekf, note):
        """The truth of ``log``, or None (no ``truth`` stream, or not of this scene: said to
        ``note``)."""
        if not (log / f"{streams.TRUTH}.csv").is_file():
            return None
        try:
            return cls(ekf, read_stream(log, streams.TRUTH))
        except (LogError, ValueError) as exc:  # a column of another scene: no field
            note(f"{log / streams.TRUTH}.csv: not scored ({exc})")
            return None

    def step(self) -> None:
        self.score.estimate()
        self._score_until(self.score.ekf.t)

    def finish(self) -> bool:
        """Score what is left; whether anything was scored."""
        self._score_until(np.inf)
        return bool(self.score.nees)

    def _score_until(self, t_s: float) -> None:
        """Hand the score the truth samples up to the first at or after ``t_s``."""
        while self.next < len(self.t_s) and (self.next == 0 or self.t_s[self.next - 1] < t_s):
            k = self.next
            self.score.truth(self.t_s[k], self.N[k], self.omega[k], self.rest[k])
            self.next += 1


def compare_live(live, times, states, layout) -> dict:
    """Largest ``|replay - run|`` per state group (:data:`GROUPS`) at the run's estimate rows.

    Parameters
    ----------
    live : structured array or None
        The run's ``estimate`` stream.
    times, states : sequences
        The replay's estimate: filter time, s, and state after every step.
    layout : FilterLayout

    Returns
    -------
    dict
        ``rows`` compared and one maximum per group (units in the key); empty if there is
        nothing to compare (no estimate in the log, or none within the replay's span).
    """
    labels = layout.labels()
    if live is None or not times or not set(labels) <= set(live.dtype.names):
        return {}
    # The replay's estimate as it stood at each of the run's rows: its last step at or before.
    at = np.searchsorted(np.asarray(times), live["t_s"], side="right") - 1
    rows = at >= 0
    if not np.any(rows):
        return {}
    run = np.column_stack([live[c] for c in labels])[rows]
    diff = np.abs(np.asarray(states)[at[rows]] - run)
    out = {"rows": int(np.sum(rows))}
    for group, attr in GROUPS.items():
        part = diff[:, getattr(layout, attr)]
        if part.size:
            out[group] = float(np.nanmax(part)) if np.any(np.isfinite(part)) else float("nan")
    return out


FUSED = (streams.IMU, streams.WHEELS, streams.SERVOS, streams.COMMAND, streams.SERVO_GOALS)
"""The streams the filter fuses: their rows are screened (:mod:`gyrohost.run.log_screen`)."""
LATER = (streams.SERVO_GOALS,)
"""Fused streams that logs made before them lack (the servos' goals came from ``command``)."""


def read_inputs(log: Path, warn: Callable[[str], None] | None = None, screen=None) -> dict:
    """The input streams of a log folder, as structured arrays.

    Without ``warn`` a stream that cannot be read raises ``LogError``; with it, unreadable rows
    are skipped and a stream whose file is missing or empty is left out, each told to ``warn``.
    ``screen`` (a :class:`~gyrohost.run.log_screen.LogScreen`) leaves out and counts the rows
    not to be fused; default: one of :data:`FUSED`, its counts then lost.
    """
    meta = read_meta(log)
    present = [n for n in (*FUSED, streams.ESTIMATE) if n in meta.get("streams", {})]
    screen = LogScreen(FUSED) if screen is None else screen
    return read_streams(log, present, warn, "replayed without it", screen)


def prepare(log, scene=None, config: EstimatorConfig | None = None, warn=None, screen=None):
    """Model, configuration, input streams and initial filter of a log folder.

    The filter runs over the span of the run's estimator (the log's ``estimate`` stream; else
    all samples); the IMU samples at the times of the IMU's grid reconstructed from all their
    arrival stamps (:func:`~gyrohost.estimator.sample_feed.regular_times`), as the run loop fuses
    them. It starts from the scene's initial state with the last
    wheel speeds, servo lengths and command before that time; earlier samples are left out.

    ``warn``, ``screen``: as :func:`read_inputs`.

    Returns
    -------
    ekf : TensegrityEKF
    data : dict of structured arrays (samples from the start on; the run's ``estimate``, if
        the log has one, whole)
    """
    log = Path(log)
    meta = read_meta(log)
    scene_path = Path(scene) if scene is not None else _scene_path(log, meta)
    if config is None:
        config = config_from_dict(meta.get("estimator", {}), f"{log}/meta.json")
    model = Model(load_scene(scene_path))
    data = read_inputs(log, warn, screen)
    if streams.IMU not in data or not len(data[streams.IMU]):
        raise LogError(f"{log}: no imu samples to replay")
    return started(model, config, data)


def started(model, config: EstimatorConfig, data: dict):
    """The filter of ``model`` and ``config`` at the start of the streams ``data`` (as
    :func:`read_inputs` returns them, at least one IMU sample), and the samples it fuses from
    there on, as :func:`prepare` describes them."""
    data = dict(data)
    live = data.pop(streams.ESTIMATE, None)
    t1 = np.inf
    if live is not None and len(live):
        t0, t1 = float(live["t_s"][0]), float(live["t_s"][-1])
    else:
        t0 = min(float(d["t_s"][0]) for d in data.values() if len(d))
    x0 = from_model_state(model, model.initial_state(), model.input_at(0.0))
    before = {k: d[d["t_s"] <= t0] for k, d in data.items()}
    if len(before.get(streams.WHEELS, ())):
        last = before[streams.WHEELS][-1]
        n_w = layout_of(model).n_wheels
        x0[layout_of(model).omega] = [last[c] for c in streams.wheel_speed_columns(n_w)]
    if len(before.get(streams.SERVOS, ())):
        last = before[streams.SERVOS][-1]
        for i, string in enumerate(model.scene.strings):
            column = streams.servo_length_column(string.name)
            if column in last.dtype.names:
                x0[layout_of(model).rest.start + i] = last[column]
    ekf = TensegrityEKF(model, config, x0=x0, t0_s=t0)
    if len(before.get(streams.COMMAND, ())):
        last = before[streams.COMMAND][-1]
        goals = before.get(streams.rest_goals(before), ())
        goal = goals[-1] if len(goals) else last
        cmd = [c for c in streams.wheel_command_columns(layout_of(model).n_wheels)
               if c in last.dtype.names]  # fmt: skip
        ekf.set_input(
            [goal[streams.rest_column(s.name)] for s in model.scene.strings],
            wheel_speed_rad_s=[last[c] for c in cmd] if cmd else None,
        )
    else:  # no command yet: the servos hold where they start (not the scene's input at t0)
        ekf.set_input(x0[layout_of(model).rest])
    after = {k: d[(d["t_s"] >= t0 if k == streams.IMU else d["t_s"] > t0) & (d["t_s"] <= t1)]
             for k, d in data.items()}  # fmt: skip
    # fused at the IMU's grid reconstructed from every arrival, as the run loop fused them
    imu = data[streams.IMU]
    kept = (imu["t_s"] >= t0) & (imu["t_s"] <= t1)
    after[streams.IMU] = imu[kept].copy()
    after[streams.IMU]["t_s"] = sample_feed.regular_times(
        imu["t_s"], config.imu_period_s, config.imu_max_delay_s
    )[kept]
    if streams.WHEELS in data:  # on the board's clock, as the run loop fused them
        wheels = data[streams.WHEELS]
        kept = (wheels["t_s"] > t0) & (wheels["t_s"] <= t1)
        after[streams.WHEELS] = wheels[kept].copy()
        after[streams.WHEELS]["t_s"] = sample_feed.wheel_times(wheels, config)[kept]
    if live is not None:
        after[streams.ESTIMATE] = live
    return ekf, after


def replay(log, out, scene=None, config: EstimatorConfig | None = None, warn=None) -> dict:
    """Run the estimator over log folder ``log``; write log folder ``out``.

    ``warn``, if given, is called with each warning about the input (a skipped row, a stream
    left out) as it is found; they are in the summary's ``warnings`` either way.

    Returns
    -------
    dict
        Counters per source, the final status word, the warnings, the input rows read and left
        out per fused stream and kind (``log_rows``, :mod:`gyrohost.run.log_screen`), the
        comparison with the
        run's estimate (``compare_live``, :func:`compare_live`); also stored in
        ``out/meta.json``.
    """
    log, out = Path(log), Path(out)
    check_new_log_folder(out)
    meta = read_meta(log)
    warnings = []

    def note(message: str) -> None:
        warnings.append(message)
        if warn is not None:
            warn(message)

    screen = LogScreen(FUSED)
    ekf, data = prepare(log, scene, config, note, screen)
    live = data.pop(streams.ESTIMATE, None)
    out_meta = {
        "replay_of": str(log),
        "scene": str(ekf.model.scene.name),
        "estimator": asdict(ekf.config),
        "source_created_unix_s": meta.get("created_unix_s"),
    }
    truth = _Truth.of(log, ekf, note)
    with RunLog(out, out_meta) as run:
        writer = _Writer(run, ekf, truth)
        ekf.log = writer.innovation
        sample_feed.run(ekf, data, writer.step)
        summary = {
            "final_status": int(ekf.status),
            "sources": {s: m.counters() for s, m in ekf.monitors.items()},
            "warnings": warnings,
            "log_rows": screen.counts(),
            "compare_live": compare_live(live, writer.times, writer.states, ekf.layout),
        }
        if truth is not None and truth.finish():
            summary["nees"] = truth.score.table()
        run.update_meta(created_unix_s=meta.get("created_unix_s", 0.0), summary=summary)
    return summary
