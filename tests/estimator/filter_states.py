"""Test helper: the model state of a filter state, to check the filter against the model."""

import numpy as np

from gyrohost.estimator.layout import layout_of


def to_model_state(model, x):
    """Model state of a filter state (wheel angles 0; the rest lengths belong to the input)."""
    F = layout_of(model)
    return np.concatenate(
        [x[F.q], x[F.q_dot], np.zeros(F.n_wheels), x[F.omega][model.torque_wheels]]
    )
