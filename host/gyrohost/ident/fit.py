"""Output-error fit of the rig's parameters to recorded runs (``scipy.optimize.least_squares``).

Every recording's inputs (servo positions, wheel speeds) drive the rig's model
(:mod:`.forward`) under a parameter vector; the residual is what the IMU reported less what the
model predicts (rate, specific force, roll, pitch), each divided by its noise standard deviation
(the rig's estimator settings, ``imu_*_std``). At the optimum the Jacobian ``J`` of these
residuals gives the covariance ``s^2 (J^T J)^-1`` with ``s^2`` the residual variance per degree of
freedom (the fit's own scatter, so a model that misses some of the motion widens its sigmas).
Directions the data cannot resolve are found from the singular values of ``J`` with unit
columns: a singular value below ``rcond`` times the largest marks a combination of parameters
the data do not determine; the parameters it involves are reported as not separable, with the
combinations of them that are determined, instead of numbers.
"""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from gyrohost.config import RigConfig
from gyrohost.estimator.config import EstimatorConfig
from gyrohost.ident import forward
from gyrohost.ident.params import OUTPUT_GROUPS, Param, apply
from gyrotensegrity import Scene

CHANNELS = ("gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z", "roll", "pitch")
STREAMS = {"gyro": slice(0, 3), "accel": slice(3, 6), "angle": slice(6, 8)}
RCOND = 1e-3
"""Singular values of the unit-column Jacobian below this fraction of the largest: not resolved."""
INVOLVED = 0.2
"""A parameter whose weight in an unresolved direction exceeds this is not separable."""


@dataclass
class FitResult:
    """The outcome of :func:`fit`.

    Attributes
    ----------
    params : list of Param
    theta, sigma : ndarray, shape (p,)
        Estimate and its 1-sigma (units of ``theta``: relative or absolute, see :class:`Param`).
    correlation : ndarray, shape (p, p)
    unresolved : list of ndarray, shape (p,) each
        Unit vectors of parameter combinations the data do not determine.
    separable : ndarray of bool, shape (p,)
        ``False`` for a parameter involved in an unresolved combination.
    residuals : list of ndarray, shape (k_i, 8)
        Measured less predicted at the optimum per recording, physical units.
    initial_residuals : list of ndarray, shape (k_i, 8)
        The same at the nominal parameters.
    rms : dict
        Stream -> (RMS at the nominal, RMS at the optimum), over all recordings.
    cost, nfev, status : float, int, str
    scene : Scene
        The nominal scene the parameters act on.
    servo_lag_s : float
        The lag the parameters start from (s).
    """

    params: list
    theta: np.ndarray
    sigma: np.ndarray
    correlation: np.ndarray
    unresolved: list
    separable: np.ndarray
    residuals: list
    initial_residuals: list
    rms: dict
    cost: float
    nfev: int
    status: str
    scene: Scene
    servo_lag_s: float

    def value(self, i: int) -> float:
        """Physical value of parameter ``i``."""
        return self.params[i].value(self.theta[i])

    def value_sigma(self, i: int) -> float:
        """Physical 1-sigma of parameter ``i``."""
        p = self.params[i]
        return self.sigma[i] * (abs(p.nominal) if p.relative else 1.0)

    def strong_correlations(self, threshold=0.8) -> list[tuple[str, str, float]]:
        """Pairs of separable parameters with |correlation| above ``threshold``."""
        names = [p.name for p in self.params]
        ok = self.separable
        return [
            (names[i], names[j], float(self.correlation[i, j]))
            for i in range(len(names))
            for j in range(i + 1, len(names))
            if ok[i] and ok[j] and abs(self.correlation[i, j]) > threshold
        ]


class Problem:
    """The weighted residual of parameter vectors over the recordings; simulations are reused
    while only output parameters change (the Jacobian's columns of mounting and biases)."""

    def __init__(self, scene: Scene, config: RigConfig, est: EstimatorConfig, params, recs):
        self.scene, self.config, self.params, self.recs = scene, config, params, recs
        self.servo_lag_s = nominal_lag(config, est, recs)
        self.weights = np.array(
            3 * [est.imu_rate_std_rad_s]
            + 3 * [est.imu_accel_std_m_s2]
            + 2 * [est.imu_angle_std_rad]
        )
        self.dynamic = np.array([p.group not in OUTPUT_GROUPS for p in params])
        self._key, self._motions = None, None
        self.simulations = 0

    def applied(self, theta):
        return apply(self.scene, self.config, self.params, theta, self.servo_lag_s)

    def motions(self, theta) -> list:
        key = tuple(np.asarray(theta)[self.dynamic])
        if key != self._key:
            a = self.applied(theta)
            self._motions = [
                forward.simulate(a.scene, self.config, r, a.offsets_m, a.servo_lag_s)
                for r in self.recs
            ]
            self._key = key
            self.simulations += 1
        return self._motions

    def errors(self, theta) -> list:
        """Predicted less measured per recording, shape (k_i, 8), physical units."""
        a = self.applied(theta)
        return [
            forward.output_error(
                forward.sensor_outputs(m, a.mounting_rpy_rad, a.gyro_bias_rad_s, a.accel_bias_m_s2),
                r,
            )
            for m, r in zip(self.motions(theta), self.recs, strict=True)
        ]

    def __call__(self, theta) -> np.ndarray:
        return np.concatenate([(e / self.weights).ravel() for e in self.errors(theta)])


def nominal_lag(config: RigConfig, est: EstimatorConfig, recs) -> float:
    """The lag to start from, s: the servos' response (the estimator's ``servo_lag_s``) for
    commanded lengths, else the rig's string lag (``[sim.truth] servo_lag_s``)."""
    return est.servo_lag_s if any(r.commanded for r in recs) else config.sim.truth.servo_lag_s


def fit(
    scene: Scene,
    config: RigConfig,
    est: EstimatorConfig,
    params: list[Param],
    recs: list,
    progress: Callable[[int, float], None] | None = None,
    max_nfev: int = 40,
) -> FitResult:
    """Fit ``params`` to the recordings ``recs`` (:class:`.forward.Recording`).

    ``progress(simulations, cost)`` is called after every residual evaluation.
    """
    problem = Problem(scene, config, est, params, recs)

    def residual(theta):
        r = problem(theta)
        if progress is not None:
            progress(problem.simulations, 0.5 * float(r @ r))
        return r

    theta0 = np.zeros(len(params))
    initial = [-e for e in problem.errors(theta0)]
    lower = np.array([p.lower for p in params])
    steps = [p.step for p in params]

    sol = least_squares(
        residual, theta0, bounds=(lower, np.inf), diff_step=steps, xtol=1e-10, max_nfev=max_nfev
    )
    final = [-e for e in problem.errors(sol.x)]
    sigma, corr, unresolved, separable = uncertainty(sol.jac, sol.fun, len(params))
    rms = {name: (_rms(initial, cols), _rms(final, cols)) for name, cols in STREAMS.items()}
    return FitResult(
        params, sol.x, sigma, corr, unresolved, separable, final, initial, rms,
        float(sol.cost), int(sol.nfev), str(sol.message), scene, problem.servo_lag_s,
    )  # fmt: skip


def _rms(errors, cols) -> float:
    return float(np.sqrt(np.mean(np.concatenate([e[:, cols] for e in errors]) ** 2)))


def uncertainty(J: np.ndarray, r: np.ndarray, p: int):
    """1-sigma, correlation, unresolved directions and separability from the Jacobian ``J``
    (n, p) of the weighted residuals ``r`` (n,) at the optimum (see the module docstring)."""
    dof = max(len(r) - p, 1)
    s2 = float(r @ r) / dof
    norms = np.linalg.norm(J, axis=0)
    norms[norms == 0.0] = 1.0
    _, sv, Vt = np.linalg.svd(J / norms, full_matrices=False)
    resolved = sv > RCOND * sv[0]
    unresolved = [Vt[i] for i in np.flatnonzero(~resolved)]
    separable = np.ones(p, bool)
    for v in unresolved:
        separable &= np.abs(v) <= INVOLVED
    # pseudo-inverse over the resolved directions: the unresolved ones would swamp the rest
    inv = (Vt[resolved].T / sv[resolved] ** 2) @ Vt[resolved]
    cov = s2 * inv / np.outer(norms, norms)
    sigma = np.sqrt(np.diag(cov))
    corr = cov / np.outer(sigma, sigma)
    sigma[~separable] = np.inf
    return sigma, corr, unresolved, separable


def determined_combinations(result: FitResult) -> list[tuple[np.ndarray, float]]:
    """Unit combinations ``c`` of the non-separable parameters that the data do determine, with
    their values ``c . theta`` (relative/absolute units of the parameters involved)."""
    idx = np.flatnonzero(~result.separable)
    if not len(idx):
        return []
    null = np.array([v[idx] for v in result.unresolved])
    _, sv, Vt = np.linalg.svd(null, full_matrices=True)
    rank = int(np.sum(sv > 1e-9))
    out = []
    for c_sub in Vt[rank:]:
        c = np.zeros(len(result.params))
        c[idx] = c_sub
        out.append((c, float(c @ result.theta)))
    return out
