"""Rerun the estimator over a run log and write its estimates and innovations to a new log.

Input: a log folder (``gyrohost.run.log``) with the streams of :mod:`.streams` (``imu``,
``wheels``, ``servos``, ``command``; any may be missing). The scene comes from ``scene`` in
``meta.json`` (a path, relative to the log folder or the working directory) unless given; the
estimator configuration from ``estimator`` in ``meta.json`` (a table of :mod:`.config` keys)
unless given.

The filter covers the span the run's estimator covered (its ``estimate`` rows) and starts with
the wheel speeds, servo lengths and command last logged before it (as the run loop does).

Output: a new log folder with the streams ``estimate`` and ``innov_<source>`` (columns in
:mod:`.streams`) and a ``meta.json`` whose creation time is the input's, so that two replays of
one log are identical byte for byte.
"""

from dataclasses import asdict
from pathlib import Path

import numpy as np

from gyrohost.estimator import driver, streams
from gyrohost.estimator.config import EstimatorConfig, config_from_dict
from gyrohost.estimator.ekf import SOURCES, TensegrityEKF
from gyrohost.estimator.errors import EstimatorConfigError
from gyrohost.estimator.imu_model import tilt
from gyrohost.estimator.layout import from_model_state, layout_of
from gyrohost.run.log import LogError, RunLog, check_new_log_folder, read_meta, read_stream
from gyrotensegrity import Model, load_scene

_LABELS = {
    "imu_rate": ("x", "y", "z"),
    "imu_accel": ("x", "y", "z"),
    "imu_angle": ("roll", "pitch", "yaw"),
}


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
    if source in _LABELS:
        return _LABELS[source]
    if source == "wheels":
        return tuple(f"w{k}" for k in range(len(model.wheel_bars)))
    return tuple(s.name for s in model.scene.strings)


class _Writer:
    """Writes the estimate after every step and every innovation as it comes."""

    def __init__(self, out: RunLog, ekf):
        self.ekf = ekf
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


def read_inputs(log: Path) -> dict:
    """The input streams present in a log folder, as structured arrays."""
    meta = read_meta(log)
    names = (streams.IMU, streams.WHEELS, streams.SERVOS, streams.COMMAND)
    return {n: read_stream(log, n) for n in names if n in meta["streams"]}


def prepare(log, scene=None, config: EstimatorConfig | None = None):
    """Model, configuration, input streams and initial filter of a log folder.

    The filter runs over the span of the run's estimator (the log's ``estimate`` stream; else
    all samples). It starts from the scene's initial state with the last
    wheel speeds, servo lengths and command before that time; earlier samples are left out.

    Returns
    -------
    ekf : TensegrityEKF
    data : dict of structured arrays (samples from the start on)
    """
    log = Path(log)
    meta = read_meta(log)
    scene_path = Path(scene) if scene is not None else _scene_path(log, meta)
    if config is None:
        config = config_from_dict(meta.get("estimator", {}), f"{log}/meta.json")
    model = Model(load_scene(scene_path))
    data = read_inputs(log)
    if streams.IMU not in data or not len(data[streams.IMU]):
        raise LogError(f"{log}: no imu samples to replay")
    t1 = np.inf
    if streams.ESTIMATE in meta["streams"] and len(est := read_stream(log, streams.ESTIMATE)):
        t0, t1 = float(est["t_s"][0]), float(est["t_s"][-1])
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
        ekf.set_input([last[streams.rest_column(s.name)] for s in model.scene.strings])
    after = {k: d[(d["t_s"] >= t0 if k == streams.IMU else d["t_s"] > t0) & (d["t_s"] <= t1)]
             for k, d in data.items()}  # fmt: skip
    return ekf, after


def replay(log, out, scene=None, config: EstimatorConfig | None = None) -> dict:
    """Run the estimator over log folder ``log``; write log folder ``out``.

    Returns
    -------
    dict
        Counters per source and the final status word (also stored in ``out/meta.json``).
    """
    log, out = Path(log), Path(out)
    check_new_log_folder(out)
    meta = read_meta(log)
    ekf, data = prepare(log, scene, config)
    out_meta = {
        "replay_of": str(log),
        "scene": str(ekf.model.scene.name),
        "estimator": asdict(ekf.config),
        "source_created_unix_s": meta.get("created_unix_s"),
    }
    with RunLog(out, out_meta) as run:
        writer = _Writer(run, ekf)
        ekf.log = writer.innovation
        driver.run(ekf, data, writer.step)
        summary = {
            "final_status": int(ekf.status),
            "sources": {s: m.counters() for s, m in ekf.monitors.items()},
        }
        run.update_meta(created_unix_s=meta.get("created_unix_s", 0.0), summary=summary)
    return summary
