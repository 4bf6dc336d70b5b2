"""Monte Carlo consistency check of the EKF on synthetic runs (and the lean model's cost).

The runs are cases of :mod:`gyrohost.parallel`; the study ``python -m studies.estimator_montecarlo``
runs 20 of them per process model.

Each run draws its own truth disturbances, gyro bias, sensor noise and initial estimate error
(seed = run index), runs the paper's D-bar manoeuvre through the reference model
(:mod:`.synthetic`) and the filter over the synthetic streams, and records at every IMU sample
the NEES (on the constraint manifold, :mod:`gyrohost.estimator.consistency`), the NIS of every
source, the tilt error and the node position error; :func:`summarise` prints the averages
against the 95 % chi-square bounds of an average over the runs, the share of time steps inside
them, tilt and position errors, cycle time.
"""

import time
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from gyrohost import parallel
from gyrohost.estimator import sample_feed, streams
from gyrohost.estimator.consistency import (
    average_bounds,
    block_nees,
    nees,
    sample_initial,
    tilt_error,
)
from gyrohost.estimator.ekf import TensegrityEKF
from gyrohost.resources import shipped
from gyrohost.sil.synthetic import sensor_streams, simulate_truth
from gyrotensegrity import Model

DEFAULT_SCENE = shipped("scene", "dbar-gyro")
TRUTH_PSD_M2_S3 = 1e-4  # density of the disturbance the synthetic truth carries
START_SEED_OFFSET = 7_000_001
"""Added to a run's seed for the draw of its filter's start: a stream of its own, apart from
the truth's and the sensors' noise of the same seed."""


@dataclass
class ScoredRun:
    """Per IMU sample of one run: t_s, nees (with nees_dof), tilt_rad, position_m (RMS node
    error of the eta2 coordinates); nis: source -> (times, values, dof); cpu_s: filter CPU time;
    blocks: block -> (values, dof), the marginal NEES of every block of the state
    (:func:`gyrohost.estimator.consistency.block_nees`), or of what a truth of positions, wheel
    speeds and rest lengths observes (:func:`~gyrohost.estimator.consistency.observed_blocks`)."""

    t_s: np.ndarray
    nees: np.ndarray
    nees_dof: int
    tilt_rad: np.ndarray
    position_m: np.ndarray
    nis: dict
    cpu_s: float
    blocks: dict = field(default_factory=dict)


def score_run(ekf, data, truth_at, nees_of=nees, feed=sample_feed.run, blocks_of=block_nees):
    """Run ``ekf`` over the streams ``data`` and score every IMU sample.

    Parameters
    ----------
    truth_at : callable(ekf) -> (x_true (n,), R_true (3, 3))
        The true filter state and sensor axes at the filter's time.
    nees_of : callable(ekf, x_true) -> (value, dof)
    feed : callable(ekf, data, on_step)
        What hands the samples to the filter (:func:`gyrohost.estimator.sample_feed.run`: all in
        time order).
    blocks_of : callable(ekf, x_true) -> dict of (value, dof), or None
        The marginal NEES of the state's blocks (None: not scored).
    """
    nis: dict = {}
    ekf.log = lambda r: nis.setdefault(r.source, []).append((r.t_s, r.nis, len(r.innovation)))
    rows, blocks = [], {}
    q = ekf.layout.q

    def score(e, stream):
        if stream == streams.IMU:
            x_true, R_true = truth_at(e)
            value, dof = nees_of(e, x_true)
            R, _ = e.attitude()
            pos = np.sqrt(np.mean((e.x[q] - x_true[q]) ** 2))
            rows.append((e.t, value, dof, tilt_error(R, R_true), pos))
            for name, (v, d) in ({} if blocks_of is None else blocks_of(e, x_true)).items():
                blocks.setdefault(name, ([], d))[0].append(v)

    c0 = time.process_time()
    feed(ekf, data, score)
    cpu = time.process_time() - c0
    t, v, dof, tilt, pos = (np.array(c) for c in zip(*rows, strict=True))
    nis_out = {s: tuple(np.array(c) for c in zip(*vals, strict=True)) for s, vals in nis.items()}
    blocks = {name: (np.array(v), d) for name, (v, d) in blocks.items()}
    return ScoredRun(t - t[0], v, int(dof[0]), tilt, pos, nis_out, cpu, blocks)


def sampled_truth(x, R, dt_s=0.01):
    """``truth_at`` for truth sampled every ``dt_s`` from t = 0: states (k, n), axes (k, 3, 3);
    the state interpolated linearly to the filter's time, the axes the nearest sample's."""

    def truth_at(ekf):
        u = min(max(ekf.t / dt_s, 0.0), len(x) - 1.0)
        k = min(int(u), len(x) - 2)
        w = u - k
        return (1.0 - w) * x[k] + w * x[k + 1], R[int(round(u))]

    return truth_at


def one_run(model, config, seed, duration_s, truth_psd_m2_s3=TRUTH_PSD_M2_S3):
    """Simulate, filter and score one run."""
    truth = simulate_truth(model, config, duration_s, seed, accel_psd_m2_s3=truth_psd_m2_s3)
    data = sensor_streams(model, config, truth, seed)
    ekf = TensegrityEKF(model, config)
    rng = np.random.default_rng(seed + START_SEED_OFFSET)
    ekf = TensegrityEKF(model, config, x0=sample_initial(ekf, truth.x[0], rng))
    return score_run(ekf, data, sampled_truth(truth.x, truth.R_ws))


def nees_average(results):
    """The NEES averaged over the runs at each step: times (k,) s from the first IMU sample,
    average (k,), dof; ``k`` the shortest run's steps."""
    k = min(len(r.t_s) for r in results)
    return results[0].t_s[:k], np.mean([r.nees[:k] for r in results], axis=0), results[0].nees_dof


def nis_average(results, source):
    """The NIS of ``source`` averaged over the runs at each of its samples: times (k,) s from
    the source's first sample, average (k,), dof; ``k`` the shortest run's samples."""
    k = min(len(r.nis[source][0]) for r in results)
    t = results[0].nis[source][0][:k]
    avg = np.mean([r.nis[source][1][:k] for r in results], axis=0)
    return t - t[0], avg, int(results[0].nis[source][2][0])


def summarise(results, label="", burn_in_s=0.2):
    """Print NEES/NIS against their bounds, tilt and position errors; return the figures.

    NEES is also given after ``burn_in_s``, without the first linearisations at the drawn
    initial error (at t = 0 both strings of the D-bar sit exactly at their rest length, the kink
    of a tension-only string, which a linearisation cannot represent).
    """
    n = len(results)
    t, nees_avg, nees_dof = nees_average(results)
    k = len(t)
    out = {"runs": n}
    out["nees"] = _report(f"{label}NEES", nees_avg, nees_dof, n)
    late = t >= burn_in_s
    out["nees_after_burn_in"] = _report(
        f"{label}NEES after {burn_in_s} s", nees_avg[late], nees_dof, n
    )
    for source in results[0].nis:
        _, avg, dof = nis_average(results, source)
        out[f"nis_{source}"] = _report(f"{label}NIS {source}", avg, dof, n)
    out["blocks"] = _blocks(results, k, label)
    tilt = np.array([r.tilt_rad[:k] for r in results])
    pos = np.array([r.position_m[:k] for r in results])
    out["tilt_rms_deg"] = float(np.degrees(np.sqrt(np.mean(tilt**2))))
    out["tilt_max_deg"] = float(np.degrees(tilt.max()))
    out["position_rms_mm"] = float(1e3 * np.sqrt(np.mean(pos**2)))
    out["cpu_per_run_s"] = float(np.mean([r.cpu_s for r in results]))
    print(
        f"{label}tilt error RMS {out['tilt_rms_deg']:.4f} deg, max {out['tilt_max_deg']:.4f} deg; "
        f"node coordinate error RMS {out['position_rms_mm']:.3f} mm; "
        f"filter CPU {out['cpu_per_run_s']:.2f} s per run ({k} IMU samples)"
    )
    return out


BLOCK_WINDOWS_S = ((0.0, 0.2), (0.2, 1.0), (1.0, 2.0), (2.0, np.inf))


def _blocks(results, k, label):
    """Print the run-averaged marginal NEES of every block over :data:`BLOCK_WINDOWS_S`, and
    the share of the steps where it lies below, inside and above its bounds (a block below at
    most steps is conservative, above overconfident: the total's misses come from those)."""
    out = {}
    t, n = results[0].t_s[:k], len(results)
    for name, (_, dof) in results[0].blocks.items():
        avg = np.mean([r.blocks[name][0][:k] for r in results], axis=0)
        windows = [_mean(avg[(t >= a) & (t < b)]) for a, b in BLOCK_WINDOWS_S]
        lo, hi = average_bounds(dof, n)
        shares = {"below": float(np.mean(avg < lo)), "above": float(np.mean(avg > hi))}
        shares["inside"] = 1.0 - shares["below"] - shares["above"]
        out[name] = {"mean": float(np.mean(avg)), "dof": dof, "windows": windows, **shares}
        spans = ", ".join(
            f"{a:g}-{b:g} s {w:.2f}" for (a, b), w in zip(BLOCK_WINDOWS_S, windows, strict=True)
        )
        steps = ", ".join(f"{100 * shares[s]:.0f} % {s}" for s in ("below", "inside", "above"))
        print(f"{label}block {name} (dof {dof}): mean {np.mean(avg):.2f}; {spans}; steps {steps}")
    return out


def _mean(values):
    return float(np.mean(values)) if values.size else float("nan")


def _report(name, avg, dof, runs):
    lo, hi = average_bounds(dof, runs)
    inside = float(np.mean((avg >= lo) & (avg <= hi)))
    mean = float(np.mean(avg))
    print(
        f"{name}: mean {mean:.2f} (dof {dof}); 95 % bounds of a {runs}-run average "
        f"[{lo:.2f}, {hi:.2f}]; time steps inside {100 * inside:.1f} %"
    )
    return {"mean": mean, "dof": dof, "lo": lo, "hi": hi, "inside": inside}


def scene_run(scene, config, duration_s, seed):
    """:func:`one_run` of the model of ``scene``: a task that travels to a Dask worker (a
    ``Model`` does not pickle; built from its scene it is the same model)."""
    return one_run(Model(scene), config, seed, duration_s)


def run_monte_carlo(model, config, runs, duration_s, first_seed=0, executor=None):
    """``runs`` runs with seeds ``first_seed, first_seed + 1, ...``, each a case of
    ``executor`` (:class:`gyrohost.parallel.Executor`; default serial in this process)."""
    task = partial(scene_run, model.scene, config, duration_s)
    seeds = range(first_seed, first_seed + runs)
    return (executor or parallel.Executor(serial=True)).map(task, seeds)
