"""Shared fixtures: the D-bar model and one synthetic run of the paper's manoeuvre."""

import pytest

from gyrohost.estimator import EstimatorConfig
from gyrohost.estimator.layout import from_model_state
from gyrohost.resources import shipped
from gyrohost.sil.montecarlo import TRUTH_PSD_M2_S3
from gyrohost.sil.synthetic import sensor_streams, simulate_truth
from gyrotensegrity import Model, Stepper, load_scene

SCENE = shipped("scene", "dbar-gyro")


@pytest.fixture(scope="session")
def scene_path():
    return SCENE


@pytest.fixture(scope="session")
def model():
    return Model(load_scene(SCENE))


@pytest.fixture(scope="session")
def config():
    return EstimatorConfig()


@pytest.fixture(scope="session")
def synthetic(model, config):
    """1 s of truth (disturbed as in the Monte Carlo) and its sensor streams, seed 11."""
    truth = simulate_truth(model, config, 1.0, seed=11, accel_psd_m2_s3=TRUTH_PSD_M2_S3)
    return truth, sensor_streams(model, config, truth, seed=11)


@pytest.fixture(scope="session")
def moving_state(model):
    """A filter state 0.8 s into the manoeuvre (nodes moving, strings taut or slack), its
    model state and input."""
    stepper = Stepper(model)
    for _ in range(80):
        stepper.step(0.01)  # the scene's rest-length schedule, held over each 10 ms
    u = model.input_at(stepper.t)
    return from_model_state(model, stepper.x, u, [0.01, -0.02, 0.005]), stepper.x.copy(), u
