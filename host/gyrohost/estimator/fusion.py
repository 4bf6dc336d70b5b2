"""The fusion step every measurement source shares: innovation, variance, NIS, gate, update.

Each source module (``fuse_*.py``) computes its predicted measurement ``h(x)`` and Jacobian
``H`` as a :class:`Measurement` and calls :func:`fuse`. The innovation ``y = z - h(x)``
(wrapped for angles), its
covariance ``S = H P H^T + R`` and the normalised innovation squared ``NIS = y^T S^-1 y`` are
computed first; the test ratio ``NIS / gate`` (gate = chi-square quantile of ``gate_probability``
with ``dim z`` degrees of freedom) decides: ``<= 1`` the sample is fused with filterpy's
``ExtendedKalmanFilter.update`` (Joseph form) and the estimate is put back on the constraint
manifold; ``> 1`` it is rejected and counted. Either way an :class:`Innovation` is returned
and passed to the filter's log callback.
"""

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular
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
    relinearising. The estimate is then put back on the constraint manifold.

    With ``ekf.fast`` the same in fewer, larger numpy operations (:func:`_fuse_fast`).

    Returns
    -------
    list of Innovation, one per measurement, in order
    """
    if getattr(ekf, "fast", False):
        return _fuse_fast(ekf, measurements)
    kf = ekf.kf
    results, keep = [], []
    for meas in measurements:
        y = meas.residual(meas.z, meas.hx)
        S = meas.H @ kf.P @ meas.H.T + meas.R
        w, log_det_S = whitened(S, y)
        result = judge(ekf, meas, y, S, w, log_det_S - log_det(meas.R))
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
        kf.update(y.reshape(-1, 1), lambda _x: H, lambda _x: np.zeros((len(y), 1)), R=R)
        ekf.constrain()
    for r in results:
        ekf.emit(r)
    return results


def _fuse_fast(ekf, measurements) -> list[Innovation]:
    """:func:`fuse` without filterpy: ``P H^T`` and ``S`` once for all measurements stacked,
    the Cholesky factors of every measurement's ``S`` and ``R`` in one batched call (NIS,
    whitened innovation, spread), one solve with the accepted measurements' ``S`` for the gain
    (filterpy inverts it) and the Joseph form as filterpy writes it. Equal to :func:`fuse` to
    round-off (tests/estimator/test_fast_fusion.py)."""
    kf = ekf.kf
    P = kf.P
    ys = [meas.residual(meas.z, meas.hx) for meas in measurements]
    H = np.vstack([meas.H for meas in measurements])
    PHt = P @ H.T
    S = H @ PHt
    ends = np.cumsum([len(y) for y in ys])
    starts = ends - [len(y) for y in ys]
    blocks = [S[a:e, a:e] + m.R for a, e, m in zip(starts, ends, measurements, strict=True)]
    w, spread = _whitened_all(blocks, ys, [m.R for m in measurements])
    results, rows, keep = [], [], []
    for i, meas in enumerate(measurements):
        results.append(judge(ekf, meas, ys[i], blocks[i], w[i], spread[i]))
        if results[-1].accepted:
            rows.extend(range(starts[i], ends[i]))
            keep.append(i)
    if keep:
        y = np.concatenate([ys[i] for i in keep])
        R = np.zeros((len(y), len(y)))
        i = 0
        for j in keep:
            k = len(ys[j])
            R[i : i + k, i : i + k] = measurements[j].R
            i += k
        H_acc, PHt_acc = H[rows], PHt[:, rows]
        K = np.linalg.solve(S[np.ix_(rows, rows)] + R, PHt_acc.T).T
        I_KH = np.eye(len(P)) - K @ H_acc
        kf.x = kf.x + (K @ y)[:, None]
        kf.P = I_KH @ P @ I_KH.T + K @ R @ K.T
        ekf.constrain()
    for r in results:
        ekf.emit(r)
    return results


def _whitened_all(blocks, ys, Rs):
    """:func:`whitened` of every ``(S, y)`` and the spreads ``log det S - log det R``: in one
    batched Cholesky where the blocks are alike in size and all positive definite, else one by
    one (then NaN where :func:`whitened` and :func:`log_det` give it)."""
    if len({len(y) for y in ys}) == 1:
        try:
            L = np.linalg.cholesky(np.stack(blocks + Rs))
        except np.linalg.LinAlgError:
            L = None
        if L is not None and np.all(np.isfinite(L)):
            n = len(ys)
            w = np.linalg.solve(L[:n], np.stack(ys)[..., None])[..., 0]
            log_dets = 2.0 * np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)
            return w, log_dets[:n] - log_dets[n:]
    pairs = [whitened(S, y) for S, y in zip(blocks, ys, strict=True)]
    spread = [log_det_S - log_det(R) for (_, log_det_S), R in zip(pairs, Rs, strict=True)]
    return [w for w, _ in pairs], spread


def judge(ekf, meas: Measurement, y, S, w, spread: float) -> Innovation:
    """The gate's verdict on one measurement (innovation ``y``, its covariance ``S``, whitened
    ``w``, ``spread``), counted in its source's monitor."""
    nis = float(w @ w)
    ratio = nis / gate(ekf.config.gate_probability, len(y))
    accepted = bool(np.isfinite(ratio) and ratio <= 1.0)
    monitor = ekf.monitors[meas.source]
    monitor.record(ekf.t, accepted)
    return Innovation(
        meas.source,
        ekf.t,
        y,
        np.diag(S).copy(),
        nis,
        ratio,
        accepted,
        monitor.rejected,
        w,
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
