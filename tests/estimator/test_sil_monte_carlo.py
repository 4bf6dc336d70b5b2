"""Reduced software-in-the-loop Monte Carlo on the simulated rig (in process, simulated clock):
6 noise seeds over the whole 3 s manoeuvre; the run-averaged NEES and the NIS of every source
must lie inside the 95 % chi-square bounds of a 6-run average. The 20-run figures:
``python -m gyrohost.estimator.sil`` (docs/estimator.md)."""

from pathlib import Path

import numpy as np
import pytest

from gyrohost.config import load_rig_config
from gyrohost.estimator.consistency import average_bounds
from gyrohost.estimator.sil import RIG_MODEL_KEYS, score_rig_model_run

CONFIG = Path(__file__).resolve().parents[2] / "configs" / "sim-rig.toml"
SEEDS = range(1, 7)
DURATION_S = 3.0
SOURCES = ("imu_rate", "imu_accel", "imu_angle", "wheels", "servos")


@pytest.fixture(scope="module")
def results():
    config = load_rig_config(CONFIG)
    return [score_rig_model_run(config, s, DURATION_S, RIG_MODEL_KEYS) for s in SEEDS]


def _inside(values, dof, runs):
    lo, hi = average_bounds(dof, runs)
    mean = float(np.mean(values))
    return lo <= mean <= hi, f"{mean:.2f} not in [{lo:.2f}, {hi:.2f}] (dof {dof}, {runs} runs)"


def test_nees_inside_its_bounds(results):
    dof = results[0].nees_dof
    assert dof == 25  # the D-bar's 33 states less the 8 bar-length constraints
    ok, why = _inside([r.nees for r in results], dof, len(results))
    assert ok, why


@pytest.mark.parametrize("source", SOURCES)
def test_nis_inside_its_bounds(results, source):
    dof = int(results[0].nis[source][2][0])
    ok, why = _inside([np.mean(r.nis[source][1]) for r in results], dof, len(results))
    assert ok, f"{source}: {why}"


def test_tilt_error_is_small(results):
    tilt_deg = np.degrees(np.concatenate([r.tilt_rad for r in results]))
    assert np.sqrt(np.mean(tilt_deg**2)) < 0.05
    assert tilt_deg.max() < 0.3


def test_rest_jitter_reaches_the_nodes_only_through_the_rest_columns_of_f(model):
    from dataclasses import replace

    from gyrohost.estimator import EstimatorConfig
    from gyrohost.estimator.layout import layout_of
    from gyrohost.estimator.process_model import ProcessModel

    pm = ProcessModel(model, replace(EstimatorConfig(), rest_jitter_psd_m2_s=2e-10))
    L, dt = layout_of(model), 0.01
    F = np.eye(L.size)
    assert np.array_equal(pm.noise(dt, F), pm.noise(dt))  # slack strings: nothing added
    F[L.q_dot, L.rest] = np.arange(1.0, 1.0 + 3 * L.m * L.n_strings).reshape(3 * L.m, L.n_strings)
    added = pm.noise(dt, F) - pm.noise(dt)
    G = F[: L.q_dot.stop, L.rest]
    assert np.allclose(added[: L.q_dot.stop, : L.q_dot.stop], 2e-10 / dt * G @ G.T)
    assert not added[L.q_dot.stop :].any() and not added[:, L.q_dot.stop :].any()
