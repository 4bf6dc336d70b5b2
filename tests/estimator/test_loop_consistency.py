"""The filter as the run loop drives it, on the simulated clock (deterministic): IMU samples
stamped on arrival and put back on the IMU's grid, every wheel telemetry frame on arrival, ticks
late by Exp(1 ms) with the commands sent then, the filter predicting to every tick. 6 runs of
the 3 s manoeuvre; the run-averaged NEES and the NIS of every source must lie inside the 95 %
chi-square bounds of a 6-run average. The figures per effect:
``python -m gyrohost.experiments.estimator_effects`` (docs/estimator.md)."""

import numpy as np
import pytest
from run_average import inside_bounds

from gyrohost.config import load_rig_config
from gyrohost.experiments.estimator_effects import CASES, score_with_effects
from gyrohost.resources import shipped

SEEDS = range(1, 7)
SOURCES = ("imu_rate", "imu_accel", "imu_angle", "wheels", "servos")


@pytest.fixture(scope="module")
def results():
    config = load_rig_config(shipped("config", "sim-rig"))
    return [score_with_effects(config, s, CASES["loop-fixed"]) for s in SEEDS]


def test_nees_inside_its_bounds(results):
    ok, why = inside_bounds([r.nees for r in results], results[0].nees_dof, len(results))
    assert ok, why


@pytest.mark.parametrize("source", SOURCES)
def test_nis_inside_its_bounds(results, source):
    dof = int(results[0].nis[source][2][0])
    ok, why = inside_bounds([np.mean(r.nis[source][1]) for r in results], dof, len(results))
    assert ok, f"{source}: {why}"
