"""The fusion step every measurement source shares: innovation, variance, NIS, gate, update.

Each source module (``fuse_*.py``) computes its predicted measurement ``h(x)`` and Jacobian
``H`` as a :class:`Measurement` and calls :func:`fuse`. The innovation ``y = z - h(x)``
(wrapped for angles), its
covariance ``S = H P H^T + R`` and the normalised innovation squared ``NIS = y^T S^-1 y`` are
computed first; the test ratio ``NIS / gate`` (gate = chi-square quantile of ``gate_probability``
with ``dim z`` degrees of freedom) decides: ``<= 1`` the sample is fused with filterpy's
``ExtendedKalmanFilter.update`` (Joseph form) and the estimate is put back on the constraint
manifold (the considered states' entries kept: :mod:`.consider`); ``> 1`` it is rejected and
counted. Either way an :class:`Innovation` is returned and passed to the filter's log callback.
"""

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular
from scipy.stats import chi2

from gyrotensegrity.fast import _fastkernel

from . import consider
from .errors import EstimatorError


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
    whitened : ndarray, shape (k,), or None
        ``L^-1 y`` with ``S = L L^T``: independent unit-variance components when consistent,
        whose squares sum to ``nis`` (the residual of a prediction-error fit,
        :mod:`gyrohost.ident.filter_fit`); NaN where ``S`` is not positive definite.
    spread : float
        ``log det S - log det R`` (>= 0, dimensionless): how much the estimate's uncertainty
        widens the innovation beyond the sensor's noise ``R``, the term the likelihood adds to
        the NIS (a fit on the NIS alone prefers parameters that widen ``S``); NaN with
        ``whitened``.
    """

    source: str
    t_s: float
    innovation: np.ndarray
    variance: np.ndarray
    nis: float
    test_ratio: float
    accepted: bool
    rejected_count: int
    whitened: np.ndarray | None = None
    spread: float = float("nan")


_GATES: dict[tuple[float, int], float] = {}


def gate(probability: float, dof: int) -> float:
    """Chi-square quantile (cached): the NIS threshold of a gate."""
    key = (probability, dof)
    if key not in _GATES:
        _GATES[key] = float(chi2.ppf(probability, dof))
    return _GATES[key]


@dataclass(frozen=True)
class Measurement:
    """One source's sample with its prediction at the current estimate.

    z, hx : (k,) measurement and prediction; H : (k, n); R : (k, k);
    residual : callable(z, hx) -> y (``np.subtract``, or wrapping for angles).
    """

    source: str
    z: np.ndarray
    hx: np.ndarray
    H: np.ndarray
    R: np.ndarray
    residual: object = np.subtract


def fuse(ekf, *measurements: Measurement) -> list[Innovation]:
    """Gate each measurement on its own NIS, then fuse the accepted ones in one update.

    All measurements were linearised at the same estimate (one IMU sample: rate, specific force
    and angles); fusing them together is the same as fusing them one after the other without
    relinearising. The estimate is then put back on the constraint manifold, and the
    considered states' entries and covariance block back to their prior (:mod:`.consider`).

    With ``ekf.fast`` the same in the compiled kernel (:func:`_fuse_fast`).

    Returns
    -------
    list of Innovation, one per measurement, in order
    """
    before = consider.snapshot(ekf)
    if getattr(ekf, "fast", False) and _fastkernel is not None:
        results = _fuse_fast(ekf, measurements)
    else:
        results = _fuse_reference(ekf, measurements)
    consider.restore(ekf, before)
    return results


def _fuse_reference(ekf, measurements) -> list[Innovation]:
    kf = ekf.kf
    results, keep = [], []
    for meas in measurements:
        y = meas.residual(meas.z, meas.hx)
        S = meas.H @ kf.P @ meas.H.T + meas.R
        w, log_det_S = whitened(S, y)
        result = judge(ekf, meas.source, y, np.diag(S), w, log_det_S - log_det(meas.R))
        results.append(result)
        if result.accepted:
            keep.append((y, meas))
    if keep:
        y = np.concatenate([k[0] for k in keep])
        H = np.vstack([k[1].H for k in keep])
        R = np.zeros((len(y), len(y)))
        i = 0
        for _, meas in keep:
            k = len(meas.z)
            R[i : i + k, i : i + k] = meas.R
            i += k
        # filterpy forms y = z - Hx(x); passing the innovation as z and 0 as Hx keeps the
        # wrapped angle residuals computed above
        try:
            kf.update(y.reshape(-1, 1), lambda _x: H, lambda _x: np.zeros((len(y), 1)), R=R)
        except np.linalg.LinAlgError:  # each S passed its Cholesky, the stacked one is singular
            sources = ", ".join(meas.source for _, meas in keep)
            what = f"t = {ekf.t:.6g} s: the update of {sources} is singular (the covariance)"
            raise EstimatorError(what, ekf.t, sources) from None
        ekf.constrain()
    for r in results:
        ekf.emit(r)
    return results


def _fuse_fast(ekf, measurements) -> list[Innovation]:
    """:func:`fuse` in one call of the compiled kernel (``_fastkernel.update``) where filterpy
    and numpy take a few dozen: the measurements stacked, each one's ``S`` factored once by
    Cholesky (NIS, gate, whitened innovation, spread), the accepted ones' ``S`` once more for
    the gain where filterpy inverts it, the Joseph form as filterpy writes it. Equal to the
    reference to round-off (tests/estimator/test_fast_fusion.py); where the accepted
    measurements' ``S`` is not positive definite the reference takes the sample."""
    kf = ekf.kf
    ys = [meas.residual(meas.z, meas.hx) for meas in measurements]
    sizes = np.array([len(y) for y in ys], np.int64)
    ends = np.cumsum(sizes)
    R = np.zeros((ends[-1], ends[-1]))
    for e, k, meas in zip(ends, sizes, measurements, strict=True):
        R[e - k : e, e - k : e] = meas.R
    probability = ekf.config.gate_probability
    gates = np.array([gate(probability, k) for k in sizes])
    n, y = len(kf.P), np.concatenate(ys)
    S_diag, w, stats = np.empty(len(y)), np.empty(len(y)), np.empty((len(ys), 3))
    x, P = np.empty(n), np.empty((n, n))
    H = np.vstack([meas.H for meas in measurements])
    work = np.empty(_fastkernel.update_work(n, len(y)))
    prior = np.ascontiguousarray(kf.P), np.ascontiguousarray(kf.x[:, 0])
    if _fastkernel.update(sizes, gates, H, y, R, *prior, S_diag, w, stats, x, P, work):
        return _fuse_reference(ekf, measurements)
    results = [
        judge(ekf, meas.source, ys[i], S_diag[e - k : e], w[e - k : e], stats[i, 1], stats[i, 0])
        for i, (e, k, meas) in enumerate(zip(ends, sizes, measurements, strict=True))
    ]
    if stats[:, 2].any():
        kf.x, kf.P = x.reshape(-1, 1), P
        ekf.constrain()
    for r in results:
        ekf.emit(r)
    return results


def judge(ekf, source: str, y, variance, w, spread: float, nis=None) -> Innovation:
    """The gate's verdict on one measurement of ``source`` (innovation ``y``, the diagonal
    ``variance`` of its covariance, whitened ``w``, ``spread``; ``nis`` given or ``w . w``),
    counted in the source's monitor."""
    nis = float(w @ w) if nis is None else float(nis)
    ratio = nis / gate(ekf.config.gate_probability, len(y))
    accepted = math.isfinite(ratio) and ratio <= 1.0
    monitor = ekf.monitors[source]
    monitor.record(ekf.t, accepted)
    return Innovation(
        source,
        ekf.t,
        y,
        np.array(variance),
        nis,
        ratio,
        accepted,
        monitor.rejected,
        np.array(w),
        float(spread),
    )


def whitened(S: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    """``L^-1 y`` for the Cholesky factor ``L`` of ``S``, and ``log det S``; NaN (so NIS NaN,
    the sample rejected) where ``S`` is not positive definite or not finite."""
    try:
        L = np.linalg.cholesky(S)
        return solve_triangular(L, y, lower=True), log_det_of_factor(L)
    except (np.linalg.LinAlgError, ValueError):
        return np.full(len(y), np.nan), float("nan")


def log_det(R: np.ndarray) -> float:
    """``log det R`` of a sensor's noise covariance; NaN where it is not positive definite (an
    attitude's noise turned by a prediction that is no rotation)."""
    try:
        return log_det_of_factor(np.linalg.cholesky(R))
    except (np.linalg.LinAlgError, ValueError):
        return float("nan")


def log_det_of_factor(L: np.ndarray) -> float:
    """``log det (L L^T)`` of a Cholesky factor ``L``."""
    return 2.0 * float(np.sum(np.log(np.diag(L))))
