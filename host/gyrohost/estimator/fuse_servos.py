"""String lengths from the servos: ``z_i = rest_i`` (m) for the strings with a servo.

A servo reports the length of string it has paid out: the string's rest length, a state of the
filter (it lags the command by the servos' response). The geometry follows through the dynamics:
the string force depends on the distance of its nodes and on this rest length.
"""

import numpy as np

from .fusion import Innovation, Measurement, fuse

SOURCE = "servos"


def predict(ekf, x, strings):
    """Predicted lengths (k,) m of the strings with indices ``strings`` and the (linear)
    Jacobian (k, n)."""
    L = ekf.layout
    H = np.zeros((len(strings), L.size))
    H[np.arange(len(strings)), L.rest.start + strings] = 1.0
    return x[L.rest][strings].copy(), H


def fuse_servos(ekf, lengths_m, strings) -> Innovation:
    """Fuse one read of string lengths (k,) m; ``strings`` (k,) are model string indices."""
    strings = np.asarray(strings, dtype=int)
    hx, H = predict(ekf, ekf.x, strings)
    R = np.eye(len(hx)) * ekf.config.servo_length_std_m**2
    return fuse(ekf, Measurement(SOURCE, np.asarray(lengths_m, float), hx, H, R))[0]
