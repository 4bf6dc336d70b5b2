"""String lengths from the servos: ``z_i = |s_i(eta2)|`` (m) for the strings with a servo.

A servo reports the length of string it has paid out, i.e. the string's rest length; the model
takes it as the distance between the string's nodes. The difference is the elastic stretch
``tension / k`` (about 1 mm on the D-bar), covered by ``servo_length_std_m``.
"""

import numpy as np

from . import complex_step
from .fusion import Innovation, Measurement, fuse

SOURCE = "servos"
UNIT = "m"


def predict(ekf, x, strings):
    """Predicted lengths (k,) m of the strings with indices ``strings`` and the Jacobian (k, n)."""
    L, dyn = ekf.layout, ekf.process.dyn
    cols = ekf.position_columns
    N, _ = ekf.batch_nodes(complex_step.perturbed(x, cols))
    S = N[:, :, dyn.string_end[strings]] - N[:, :, dyn.string_start[strings]]
    value, J = complex_step.split(np.sqrt(np.sum(S * S, axis=1)))
    H = np.zeros((len(strings), L.size))
    H[:, cols] = J
    return value, H


def fuse_servos(ekf, lengths_m, strings) -> Innovation:
    """Fuse one read of string lengths (k,) m; ``strings`` (k,) are model string indices."""
    strings = np.asarray(strings, dtype=int)
    hx, H = predict(ekf, ekf.x, strings)
    R = np.eye(len(hx)) * ekf.config.servo_length_std_m**2
    return fuse(ekf, Measurement(SOURCE, np.asarray(lengths_m, float), hx, H, R))[0]
