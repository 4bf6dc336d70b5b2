"""The identified constants' errors considered, not estimated (a Schmidt-Kalman filter).

The IMU's mounting, the strings' stiffness and damping, the wheels' J3, the IMU's latency and
the goal delay are constants of a run, known to the 1-sigma of the recording that identified
them (``gyrotens identify``'s overlay) or of a derivation (the goal delay's USB frame). Their
errors are states so that the covariance carries what they do to the motion
(:mod:`.param_errors`, :func:`.imu_prediction.with_mounting`, :mod:`.imu_latency`). Estimated,
a run's seconds cannot know them better than their prior, but the filter's linearisation
believes it can: a transient the model misses (a pull's onset at a string's kink) lands in the
damping's error at three sigmas and, held for the rest of the run, drives the nodes off; the
paper's manoeuvre, a tip about one axis, leaves a direction of the mounting unobserved and the
filter still narrows it (reports/estimator-history.md, "The gyro's share of the held-out
misses").

Considered (``parameter_errors = "considered"``, the default), each update's gain is zero in
their rows: their estimate stays the prior's (zero error) and their covariance block the
prior's, while the other states' estimate and covariance, and the cross terms, are the
Kalman update's. That is the Joseph form with those rows of the gain zeroed, which holds for any
gain, so the filter stays consistent; and it is the optimal update's result with the
considered entries of the state and their covariance block put back, since with the gain
``K = P H^T S^-1``, ``E`` keeping the estimated rows, ``M = K S K^T``:
``(I - E K H) P (I - E K H)^T + E K R K^T E = P - E M - M E + E M E``, which is ``P - M`` but
in the considered block, there ``P``. So the update (filterpy's, or the compiled kernel's) runs
as it is and :func:`restore` puts the block back.
"""

import numpy as np


def considered_columns(layout, mode: str) -> np.ndarray:
    """State indices (k,) whose errors the filter considers: the mounting's and the parameter
    errors' (:attr:`.layout.FilterLayout.params`) where ``mode`` is ``"considered"``, none where
    it is ``"estimated"``."""
    if mode == "estimated":
        return np.zeros(0, dtype=int)
    return np.r_[
        layout.mounting.start : layout.mounting.stop, layout.params.start : layout.params.stop
    ].astype(int)


def snapshot(ekf):
    """The considered entries of the estimate and their covariance block before an update
    (None where nothing is considered)."""
    c = ekf.considered
    if c.size == 0:
        return None
    return ekf.x[c].copy(), ekf.P[np.ix_(c, c)].copy()


def restore(ekf, before) -> None:
    """Put the considered entries and their covariance block back to ``before``
    (:func:`snapshot`): the update's other entries stand (module docstring). Raising that
    block back adds a positive semi-definite matrix: the covariance stays one."""
    if before is None:
        return
    c = ekf.considered
    x, P = ekf.kf.x, ekf.kf.P
    x[c, 0] = before[0]
    P[np.ix_(c, c)] = before[1]
