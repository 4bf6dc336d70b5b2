"""Where a replay's filter starts (``gyrotens replay``, the filter fit): at the earliest row,
its inputs from the last command before it, or, with none yet, the rest lengths it starts with
held; never the scene's own input at the log's time, which a log on host time has nothing to
do with (the filter fit's recordings start with a wheel report before the first command)."""

import numpy as np
import pytest

from gyrohost.estimator import EstimatorConfig, streams
from gyrohost.estimator.layout import layout_of
from gyrohost.resources import shipped
from gyrohost.run.replay import read_inputs, started
from gyrotensegrity import Model, load_scene


@pytest.fixture(scope="module")
def data(realtime_run):
    """A real-time run's streams from 1 s on, without the live estimate, its commands starting
    after the first wheel report and servo read."""
    folder = realtime_run
    data = read_inputs(folder)
    data.pop(streams.ESTIMATE)
    # a window 1 s into the log, as the filter fit cuts its recordings at the lead-in
    data = {name: rows[rows["t_s"] >= 1.0] for name, rows in data.items()}
    first = max(data[streams.WHEELS]["t_s"][0], data[streams.SERVOS]["t_s"][0])
    data[streams.COMMAND] = data[streams.COMMAND][data[streams.COMMAND]["t_s"] > first + 0.05]
    return data


def test_without_a_command_before_the_start_the_servos_hold_where_they_start(data):
    model = Model(load_scene(shipped("scene", "dbar-gyro")))
    ekf, _ = started(model, EstimatorConfig(), data)
    rest = ekf.x[layout_of(model).rest]
    servo = data[streams.SERVOS][0]
    read = [servo[streams.servo_length_column(s.name)] for s in model.scene.strings]
    assert ekf.t > 1.0  # host time: the scene's own input there is a pull under way
    assert np.abs(model.input_at(ekf.t)[: model.alpha] - read).max() > 0.05
    np.testing.assert_array_equal(ekf.u[: model.alpha], rest)
    np.testing.assert_allclose(rest, read, atol=1e-12)
    ekf.advance(ekf.t + 0.02)  # nothing pulls: the structure stays at rest
    assert np.abs(ekf.x[layout_of(model).q_dot]).max() < 1e-3
