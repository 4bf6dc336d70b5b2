"""The rigid motion that best fits node velocities (the structure's turn in the tests)."""

import numpy as np


def structure_rate(N, N_dot):
    """Angular velocity (3,) rad/s of the rigid motion that best fits the node velocities."""
    c = N.mean(axis=1, keepdims=True)
    rows = []
    for p in (N - c).T:
        skew = np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
        rows.append(np.hstack([-skew, np.eye(3)]))
    return np.linalg.lstsq(np.vstack(rows), N_dot.T.ravel(), rcond=None)[0][:3]
