"""String lengths from the servos: ``z_i = rest_i`` (m) for the strings with a servo.

A servo reports the length of string it has paid out: the string's rest length, a state of the
filter (it lags the command by the servos' response). The geometry follows through the dynamics:
the string force depends on the distance of its nodes and on this rest length.
"""

import numpy as np

from .fusion import Innovation, Measurement, fuse
from .servo_motion import rest_before

SOURCE = "servos"


def predict(ekf, x, strings, lag_s=0.0):
    """Predicted lengths (k,) m of the strings with indices ``strings`` ``lag_s`` before the
    filter's time, and the (linear) Jacobian (k, n).

    A read sampled before the filter's time (the run loop predicts to every tick) is compared
    with the rest lengths taken back along the servos' motion through the goals in effect
    meanwhile (:func:`.servo_motion.rest_before`): towards a goal ``c``, ``rest(t - lag) = c +
    (rest(t) - c) exp(lag / servo_lag_s)`` within the lag, back along the speed limit beyond.
    """
    L = ekf.layout
    rest, gain = rest_before(ekf, x[L.rest], lag_s)
    H = np.zeros((len(strings), L.size))
    H[np.arange(len(strings)), L.rest.start + strings] = gain[strings]
    return rest[strings], H


def fuse_servos(ekf, lengths_m, strings, lag_s=0.0) -> Innovation:
    """Fuse one read of string lengths (k,) m sampled ``lag_s`` (s) before the filter's time;
    ``strings`` (k,) are model string indices.

    Taken back over the lag, the rest lengths miss the random walk they made since the read
    (``rest_psd_m2_s lag_s``, the walk's variance over the lag): it adds to the read's noise.
    So does, while a servo moves, its read's offset from the rest length the strings pull with,
    as a time (``servo_time_std_s``) through the rest length's rate in the model,
    ``(command - rest) / servo_lag_s`` at most the speed limit: a servo at rest reads exactly
    where it holds.
    """
    strings = np.asarray(strings, dtype=int)
    hx, H = predict(ekf, ekf.x, strings, lag_s)
    c = ekf.config
    rate = ekf.process.servo_speed(ekf.x[ekf.layout.rest], ekf.u)[strings]
    R = np.diag(
        c.servo_length_std_m**2 + c.rest_psd_m2_s * lag_s + (c.servo_time_std_s * rate) ** 2
    )
    return fuse(ekf, Measurement(SOURCE, np.asarray(lengths_m, float), hx, H, R))[0]
