"""The output-error fit's sigmas where its residuals are correlated in time (ident/correlated).

A constant fitted to a first-order autoregression of unit variance and coefficient rho: the
mean's variance is ``(1 + rho) / (1 - rho)`` times what white residuals give, so its sigma is
``sqrt((1 + rho) / (1 - rho))`` times wider. The Bartlett estimate of it falls short by a share
of order ``1 / L`` and scatters by about ``sqrt(4 L / 3 n)`` in the variance, half that in the
sigma (Andrews 1991). Over n = 2,000,000 samples the bandwidth is about 650 at rho 0.9 and 170
at 0.5: a scatter of 1.0 and 0.5 % in the sigma and a shortfall of a fraction of a per cent,
so 80-105 % of the true widening is more than four scatters either side; white residuals
(bandwidth a few samples) stay within 10 % of 1 by far more.
"""

import numpy as np
import pytest
from scipy.signal import lfilter

from gyrohost.ident import correlated

N = 2_000_000


def autoregression(rho: float, n: int = N, seed: int = 7) -> np.ndarray:
    """``n`` samples of a stationary first-order autoregression of unit variance."""
    rng = np.random.default_rng(seed)
    e = rng.normal(size=n) * np.sqrt(1.0 - rho**2)
    e[0] = rng.normal()  # the first sample from the stationary spread
    return lfilter([1.0], [1.0, -rho], e)


def mean_widening(r: np.ndarray, sizes=None) -> tuple[float, int]:
    """The widening of a constant's sigma fitted to residuals ``r``, and the bandwidth."""
    J = np.ones((len(r), 1))
    s2 = float(r @ r) / (len(r) - 1)
    cov = s2 * np.linalg.inv(J.T @ J)
    hac, lags = correlated.sandwich(cov, s2, J, r, sizes or [len(r)], 1)
    return correlated.widening(cov, hac, np.ones(1)), lags


@pytest.mark.parametrize("rho", [0.5, 0.9])
def test_correlated_residuals_widen_the_sigma_as_their_autoregression_says(rho):
    factor, lags = mean_widening(autoregression(rho))
    expected = np.sqrt((1.0 + rho) / (1.0 - rho))
    assert 0.8 * expected <= factor <= 1.05 * expected
    assert lags > 10  # a correlation that runs: many lags


def test_white_residuals_leave_the_sigma_nearly_as_it_was():
    factor, lags = mean_widening(autoregression(0.0))
    assert 1.0 <= factor <= 1.1
    assert lags <= 5


def test_a_sigma_is_never_narrowed():
    """Alternating residuals would say the mean is known better than white noise allows."""
    factor, _ = mean_widening(autoregression(-0.5))
    assert factor == 1.0
    cov = np.diag([1.0, 0.0])
    assert correlated.widening(cov, np.eye(2), np.array([0.0, 1.0])) == 1.0


def test_lags_do_not_reach_across_recordings():
    a, b = autoregression(0.5, 500, seed=1), autoregression(0.5, 700, seed=2)
    g = [a[:, None], b[:, None]]
    together = correlated.long_run(g, 12)
    apart = correlated.long_run(g[:1], 12) + correlated.long_run(g[1:], 12)
    np.testing.assert_allclose(together, apart, rtol=1e-12)


def test_scores_sum_each_samples_channels():
    J = np.arange(12.0).reshape(6, 2)
    r = np.array([1.0, -1.0, 2.0, 0.5, 0.0, 3.0])
    g = correlated.scores(J, r, [2, 1], 2)
    np.testing.assert_allclose(g[0], [J[0] - J[1], 2 * J[2] + 0.5 * J[3]])
    np.testing.assert_allclose(g[1], [3 * J[5]])


def test_residuals_that_are_not_whole_samples_are_refused():
    with pytest.raises(ValueError, match="7 residuals: not 2 channels for each of the 3 samples"):
        correlated.scores(np.zeros((7, 1)), np.zeros(7), [3], 2)


def test_the_report_names_the_bandwidth_and_the_widened_sigmas_only():
    from gyrohost.ident.fit import FitResult
    from gyrohost.ident.params import Param
    from gyrohost.ident.report import report_lines

    params = [Param("J3", "J3", True, 1e-5, "kg m^2"), Param("mounting.yaw", "mounting", False,
                                                             0.0, "rad")]  # fmt: skip
    result = FitResult(
        params, np.zeros(2), np.array([0.01, 0.02]), np.eye(2), [], np.ones(2, bool), [], None,
        [], [], {}, 0.0, 0, "", None, 0.0, correlated={"J3": 1.001, "mounting.yaw": 4.1},
        correlation_lags=140,
    )  # fmt: skip
    (line,) = [t for t in report_lines(result) if t.startswith("residuals correlated")]
    assert "over 140 IMU samples: 1-sigma widened mounting.yaw x4.10 (" in line
    assert "J3" not in line  # 1.00 as printed: not a widening worth a word
