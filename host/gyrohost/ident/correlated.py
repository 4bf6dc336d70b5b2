"""Sigmas of the output-error fit that hold where its residuals are correlated in time.

The linearised covariance ``C = s^2 (J^T J)^+`` (:func:`.fit.uncertainty`) counts every
weighted residual as independent noise. Where the model follows the log to the sensors' noise
they are; where it does not (a truth the nominal scene is far from, an effect the model lacks)
the misfit is a slow error that runs over many samples, each counted as new evidence, and the
sigmas come out too small however the variance ``s^2`` is scaled.

The sandwich covariance ``C_hac = A S A``, with ``A = C / s^2`` and ``S`` the long-run
covariance of the per-sample scores ``g_t = J_t^T r_t`` (the gradient of the cost that sample
``t``'s channels give), holds either way: ``S`` sums the scores' autocovariances up to a
bandwidth ``L`` with Bartlett weights ``1 - l / (L + 1)`` (Newey and West, Econometrica 1987),
which keeps it positive semi-definite. ``L`` is read off the scores themselves, each
standardised and fitted as a first-order autoregression (Andrews, Econometrica 1991, the AR(1)
plug-in for the Bartlett kernel): near 1 for white scores, tens of samples for a misfit that
runs for a fraction of a second. With white residuals ``S`` is ``s^2 J^T J`` in expectation and
``C_hac`` is ``C``.

A parameter's sigma is widened by ``sqrt(v^T C_hac v / v^T C v)`` along its direction ``v``,
never narrowed: the ratio is itself an estimate, a few per cent off 1 on white residuals, and a
sigma below the sensors' noise alone would claim more than the log holds.
"""

import numpy as np

ANDREWS_BARTLETT = 1.1447
"""The constant of the Bartlett kernel's optimal bandwidth ``1.1447 (alpha n)^(1/3)``
(Andrews 1991, eq. 6.2)."""


def scores(J: np.ndarray, r: np.ndarray, sizes, channels: int) -> list[np.ndarray]:
    """Per recording, every sample's score ``J_t^T r_t`` summed over its ``channels`` residual
    entries, shape (k_i, p). ``sizes``: the samples ``k_i`` of each recording, in the order of
    the rows of ``J`` and entries of ``r`` (sample-major, ``channels`` per sample)."""
    n, p = J.shape
    if n != channels * sum(sizes):
        raise ValueError(
            f"{n} residuals: not {channels} channels for each of the {sum(sizes)} samples"
        )
    g = (J * r[:, None]).reshape(-1, channels, p).sum(axis=1)
    return np.split(g, np.cumsum(sizes)[:-1])


def bandwidth(blocks: list[np.ndarray]) -> int:
    """The Bartlett bandwidth (lags, samples) of the score ``blocks`` (Andrews' AR(1) plug-in
    over their standardised components; lags never cross from one block to the next)."""
    lead = np.concatenate([b[1:] for b in blocks])
    lag = np.concatenate([b[:-1] for b in blocks])
    spread = np.sqrt(np.mean(np.concatenate(blocks) ** 2, axis=0))
    live = spread > 0.0
    if not np.any(live) or len(lag) < 2:
        return 0
    lead, lag = lead[:, live] / spread[live], lag[:, live] / spread[live]
    rho = np.clip(np.sum(lead * lag, axis=0) / np.sum(lag * lag, axis=0), -0.99, 0.99)
    var = np.mean((lead - rho * lag) ** 2, axis=0)  # the innovation variance of the AR(1)
    num = np.sum(4.0 * rho**2 * var**2 / ((1.0 - rho) ** 6 * (1.0 + rho) ** 2))
    den = np.sum(var**2 / (1.0 - rho) ** 4)
    n = sum(len(b) for b in blocks)
    lags = int(ANDREWS_BARTLETT * (num / den * n) ** (1.0 / 3.0))
    return min(lags, max(len(b) for b in blocks) - 1)


def long_run(blocks: list[np.ndarray], lags: int) -> np.ndarray:
    """The scores' long-run covariance ``S``, shape (p, p): within each block the lag-0 to
    lag-``lags`` autocovariance sums, Bartlett-weighted, added over the blocks."""
    p = blocks[0].shape[1]
    S = np.zeros((p, p))
    for g in blocks:
        S += g.T @ g
        for lag in range(1, min(lags, len(g) - 1) + 1):
            G = g[lag:].T @ g[:-lag]
            S += (1.0 - lag / (lags + 1.0)) * (G + G.T)
    return S


def sandwich(cov: np.ndarray, s2: float, J: np.ndarray, r: np.ndarray, sizes, channels: int):
    """The covariance ``C_hac`` (p, p) of the fit whose linearised covariance is ``cov`` with
    residual variance ``s2`` (module docstring), and the bandwidth it used (samples)."""
    blocks = scores(J, r, sizes, channels)
    lags = bandwidth(blocks)
    n, p = J.shape
    A = cov / s2
    return A @ (long_run(blocks, lags) * n / max(n - p, 1)) @ A, lags


def widening(cov: np.ndarray, hac: np.ndarray, v: np.ndarray) -> float:
    """How much wider than ``cov`` says the sigma along direction ``v`` is by ``hac``: at
    least 1 (module docstring); 1 where ``cov`` gives that direction no variance."""
    white = float(v @ cov @ v)
    if not white > 0.0:
        return 1.0
    return max(1.0, float(np.sqrt(max(float(v @ hac @ v), 0.0) / white)))
