"""The fusion step every measurement source shares: innovation, variance, NIS, gate, update.

Each source module (``fuse_*.py``) computes its predicted measurement ``h(x)`` and Jacobian
``H`` and calls :func:`fuse`. The innovation ``y = z - h(x)`` (wrapped for angles), its
covariance ``S = H P H^T + R`` and the normalised innovation squared ``NIS = y^T S^-1 y`` are
computed first; the test ratio ``NIS / gate`` (gate = chi-square quantile of ``gate_probability``
with ``dim z`` degrees of freedom) decides: ``<= 1`` the sample is fused with filterpy's
``ExtendedKalmanFilter.update`` (Joseph form) and the estimate is conditioned on the constraint
manifold; ``> 1`` it is rejected and counted. Either way an :class:`Innovation` is returned
and passed to the filter's log callback.
"""

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2


@dataclass(frozen=True)
class Innovation:
    """One fusion attempt of one source.

    Attributes
    ----------
    source : str
    t_s : float, s
    innovation : ndarray, shape (k,), unit of the measurement
    variance : ndarray, shape (k,), diagonal of S (unit^2)
    nis : float
        Normalised innovation squared, chi-square with k degrees of freedom when consistent.
    test_ratio : float
        ``nis / gate``; the sample is fused when it is at most 1.
    accepted : bool
    rejected_count : int
        Rejections of this source so far (this one included).
    """

    source: str
    t_s: float
    innovation: np.ndarray
    variance: np.ndarray
    nis: float
    test_ratio: float
    accepted: bool
    rejected_count: int


_GATES: dict[tuple[float, int], float] = {}


def gate(probability: float, dof: int) -> float:
    """Chi-square quantile (cached): the NIS threshold of a gate."""
    key = (probability, dof)
    if key not in _GATES:
        _GATES[key] = float(chi2.ppf(probability, dof))
    return _GATES[key]


def fuse(ekf, source: str, z, hx, H, R, residual=np.subtract) -> Innovation:
    """Gate and fuse one measurement into ``ekf`` (a :class:`~.ekf.TensegrityEKF`).

    Parameters
    ----------
    ekf : TensegrityEKF
    source : str
        Name of the source (its monitor counts rejections).
    z, hx : ndarray, shape (k,)
        Measurement and its prediction at the current estimate.
    H : ndarray, shape (k, n)
    R : ndarray, shape (k, k)
    residual : callable(z, hx) -> y, optional
    """
    kf = ekf.kf
    y = residual(z, hx)
    S = H @ kf.P @ H.T + R
    nis = float(y @ np.linalg.solve(S, y))
    ratio = nis / gate(ekf.config.gate_probability, len(z))
    accepted = bool(np.isfinite(ratio) and ratio <= 1.0)
    monitor = ekf.monitors[source]
    if accepted:
        kf.update(
            z.reshape(-1, 1),
            lambda _x: H,
            lambda _x: hx.reshape(-1, 1),
            R=R,
            residual=lambda a, b: residual(a.ravel(), b.ravel()).reshape(-1, 1),
        )
        ekf.constrain()
    monitor.record(ekf.t, accepted)
    result = Innovation(source, ekf.t, y, np.diag(S).copy(), nis, ratio, accepted, monitor.rejected)
    ekf.emit(result)
    return result
