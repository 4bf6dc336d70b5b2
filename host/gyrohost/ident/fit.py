"""Output-error fit of the rig's parameters to recorded runs (``scipy.optimize.least_squares``).

Every recording's inputs (servo positions, wheel speeds) drive the rig's model
(:mod:`.forward`) under a parameter vector; the residual is what the IMU reported less what the
model predicts (rate, specific force, the attitude's tilt), each divided by its noise standard
deviation (the rig's estimator settings, ``imu_*_std``; the tilt's mapped from the angles' by
:func:`.forward.tilt_std`). At the optimum the Jacobian ``J`` of these
residuals gives the linearised covariance ``s^2 (J^T J)^-1`` with ``s^2`` the residual variance
per degree of freedom. Directions the data cannot resolve are found from the singular values of
``J`` with unit columns (below ``rcond`` times the largest), and, for the D-bar's common scale of
masses, inertias, stiffness and damping, from the cost re-minimised with that scale held
(:func:`.profile.scale_rise`); the parameters they involve are reported as not separable, with
the combinations of them that are determined. The sigmas of the parameters that need a
simulation are then read off the cost along their profile directions
(:func:`.profile.secant_sigma`), which counts the roughness of the fixed-step model's cost.
"""

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from gyrohost.config import RigConfig
from gyrohost.estimator.config import EstimatorConfig
from gyrohost.ident import correlated, forward, lsq, profile, shooting, weighing
from gyrohost.ident.params import OUTPUT_GROUPS, Param, apply
from gyrotensegrity import Scene
from gyrotensegrity.errors import SimulationError

from .errors import FitError

FAILED_RESIDUAL = 1e3
"""Every residual the model could not give under a parameter vector (a simulation gone
non-finite; from where a filter broke to the recording's end): a step of the fit into such
parameters is refused as far worse than any the model runs through."""


def broken_at(params, theta, what: str) -> str:
    """``what`` broke, and the parameter values it broke at."""
    values = ", ".join(f"{p.name} {p.value(t):.6g}" for p, t in zip(params, theta, strict=True))
    return f"{what} at {values}"


class WalledResiduals:
    """Residual vectors of one length, walled where the model broke (:class:`Problem`,
    :class:`.filter_fit.FilterProblem`): the first evaluation sets the length, and a break
    there is an :attr:`error`; a later break, or a residual of another length, names its
    parameter vector in ``failures`` and fills its residuals from where it broke on with
    :data:`FAILED_RESIDUAL`. Needs ``params``, ``failures`` and ``_length``."""

    error: type[FitError] = FitError

    def _walled(self, theta, w: np.ndarray, broke: str) -> np.ndarray:
        """``w`` of ``theta``, walled if ``broke`` says what broke ("": nothing)."""
        if self._length is None:
            if broke:
                raise self.error(broken_at(self.params, theta, broke))
            self._length = len(w)
        if not broke and len(w) != self._length:
            # a residual of another shape compares nothing with the others: walled as a break
            broke = f"{len(w)} residuals where the first evaluation had {self._length}"
        if broke:
            self.failures.append(broken_at(self.params, theta, broke))
            w = np.nan_to_num(w[: self._length], nan=FAILED_RESIDUAL)
            w = np.pad(w, (0, self._length - len(w)), constant_values=FAILED_RESIDUAL)
        return w

    def residual_variance(self, r: np.ndarray, p: int) -> float:
        """The noise variance of the whitened residuals ``r`` with ``p`` parameters fitted
        (1 where the noise model is right): ``r @ r / (n - p)``."""
        return float(r @ r) / max(len(r) - p, 1)


CHANNELS = ("gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z", "tilt x", "tilt y")
STREAMS = {"gyro": slice(0, 3), "accel": slice(3, 6), "angle": slice(6, 8)}
RCOND = 1e-3
"""Singular values of the unit-column Jacobian below this fraction of the largest: not resolved."""
INVOLVED = 0.2
"""A parameter whose weight in an unresolved direction exceeds this is not separable."""
DETERMINED_SIGMA = 1.0
"""A separable parameter whose 1-sigma reaches this, in its units of ``theta`` (a factor e of
a relative one, a radian of the mounting, 1 rad/s of a gyro bias), or is infinite (its cost not
convex) is not determined: past the roll-over or on a log the rig could not record in real
time the fit ends anywhere (docs/identification.md), and the scene keeps its nominal."""
SCALE_GROUPS = ("J3", "J3-each", "bar-mass", "bar-inertia", "stiffness", "damping")
"""Groups that scale together without changing the D-bar's motion much (every mass, inertia,
stiffness and damping; the wheels' mass and transverse inertia, which are kept, break it)."""
SEGMENTED_FTOL = 1e-6
"""Relative change of the cost that ends a fit in segments: some 0.005 cost units on the
real-time rig's logs, far below the cost's roughness (about 1); the default (1e-8) went on
for twice the simulations to the same estimates (reports/identification-history.md)."""
BAR_GROUPS = ("bar-mass", "bar-inertia")
"""The scale is only free, and tested, with one of these fitted: weighed bars pin it."""


@dataclass
class FitResult:
    """The outcome of :func:`fit`.

    Attributes
    ----------
    params : list of Param
    theta, sigma : ndarray, shape (p,)
        Estimate and its 1-sigma (units of ``theta``: relative or absolute, see :class:`Param`):
        read off the cost for the parameters that need a simulation, linearised for the
        others; ``inf`` for a parameter that is not separable or whose cost is not convex.
    correlation : ndarray, shape (p, p)
    unresolved : list of ndarray, shape (p,) each
        Unit vectors of parameter combinations the data do not determine.
    separable : ndarray of bool, shape (p,)
        ``False`` for a parameter involved in an unresolved combination.
    combinations : list of (ndarray shape (p,), float, float)
        Combinations ``c`` of the non-separable parameters that the data determine, with
        ``c . theta`` and its 1-sigma.
    scale_valley : ndarray, shape (p,), or None
        The direction of the common scale of masses, inertias, stiffness and damping when the
        data do not determine it (else ``None``); the identified scene moves the estimate along
        it until the bars' parameter is at its nominal.
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
    dropped : list of (str, float, float)
        Segments left out as not predictable (:func:`.shooting.predictable`): recording, start
        and end (s from its lead-in).
    widened : dict
        Output parameter -> the factor its sigma was widened by because the segments disagree
        about it beyond their noise (:func:`.profile.segment_spread`).
    correlated : dict
        Parameter -> the factor by which the residuals' correlation in time widens its sigma
        (:mod:`.correlated`), where above 1; the larger of it and ``widened`` is applied.
    correlation_lags : int
        The bandwidth of that correlation, IMU samples (0: not estimated).
    start_line : (str, float, list of (float, float)) or None
        The parameter the fit started from the smooth minimum along (:func:`.profile.
        line_start`), that start and the samples, each an offset from its nominal (its units
        of ``theta``) and a cost; None where the fit started from the nominal.
    latency_starts : list of (float, float, float)
        The IMU latency's starts of the first solve (:func:`latency_starts`): each start, the
        cost it ended at and the latency there, s; empty where it had one start.
    strings_valley : list of (float, float)
        The optima along the strings' valley (:func:`.profile.strings_valley`): offset (valley
        steps) and cost; empty where the fit is not in segments.
    residual_variance : float
        The weighted residuals' variance per degree of freedom at the optimum
        (:meth:`WalledResiduals.residual_variance`): near 1 where the model follows the log to
        the sensors' noise.
    mass_sensitivity : ndarray, shape (p,), or None
        How the optimum moves with the log of the bars' mass (:mod:`.weighing`); None where no
        parameter scales with the masses, or a group of :data:`BAR_GROUPS` is fitted (the
        masses are not taken as weighed).
    weighing_sigma : ndarray, shape (p,), or None
        The weighing's relative 1-sigma included in ``sigma`` (:func:`.weighing.with_weighing`;
        None: not included).
    channels : tuple of str
        The columns of ``residuals``.
    streams : dict
        Stream -> its slice of ``channels``.
    """

    params: list
    theta: np.ndarray
    sigma: np.ndarray
    correlation: np.ndarray
    unresolved: list
    separable: np.ndarray
    combinations: list
    scale_valley: np.ndarray | None
    residuals: list
    initial_residuals: list
    rms: dict
    cost: float
    nfev: int
    status: str
    scene: Scene
    servo_lag_s: float
    dropped: list = field(default_factory=list)
    widened: dict = field(default_factory=dict)
    strings_valley: list = field(default_factory=list)
    residual_variance: float = float("nan")
    mass_sensitivity: np.ndarray | None = None
    weighing_sigma: np.ndarray | None = None
    correlated: dict = field(default_factory=dict)
    correlation_lags: int = 0
    start_line: tuple | None = None
    latency_starts: list = field(default_factory=list)
    channels: tuple = CHANNELS
    streams: dict = field(default_factory=lambda: dict(STREAMS))

    @property
    def determined(self) -> np.ndarray:
        """Separable parameters whose 1-sigma is below :data:`DETERMINED_SIGMA`, shape (p,)."""
        return self.separable & (self.sigma < DETERMINED_SIGMA)

    def value(self, i: int) -> float:
        """Physical value of parameter ``i``."""
        return self.params[i].value(self.theta[i])

    def value_sigma(self, i: int) -> float:
        """Physical 1-sigma of parameter ``i``: a log factor's sigma times the value it gives
        (its derivative), not the nominal one, which a value far from it would scale."""
        p = self.params[i]
        return self.sigma[i] * (abs(self.value(i)) if p.relative else 1.0)

    def strong_correlations(self, threshold=0.8) -> list[tuple[str, str, float]]:
        """Pairs of determined parameters with |correlation| above ``threshold``."""
        names = [p.name for p in self.params]
        ok = self.determined
        return [
            (names[i], names[j], float(self.correlation[i, j]))
            for i in range(len(names))
            for j in range(i + 1, len(names))
            if ok[i] and ok[j] and abs(self.correlation[i, j]) > threshold
        ]


class Problem(WalledResiduals):
    """The weighted residual of parameter vectors over the recordings; simulations are reused
    while only output parameters change (the Jacobian's columns of mounting and biases)."""

    def __init__(self, scene: Scene, config: RigConfig, est: EstimatorConfig, params, recs):
        self.scene, self.config, self.params, self.recs = scene, config, params, recs
        self.est = est
        self.servo_lag_s = nominal_lag(est, recs)
        self.imu_latency_s = est.imu_latency_s
        self.frame_nodes = est.imu_frame_nodes
        self.weights = [
            forward.noise_std(
                r, est.imu_rate_std_rad_s, est.imu_accel_std_m_s2, est.imu_angle_std_rad
            )
            for r in recs
        ]
        self.dynamic = np.array([p.group not in OUTPUT_GROUPS for p in params])
        self._key, self._motions = None, None
        self.simulations = 0
        self.failures: list[str] = []  # parameter vectors the simulation broke at (profile)
        self._length = None  # residuals per evaluation, as the first one gave

    def applied(self, theta):
        return apply(self.scene, self.config, self.params, theta, self.servo_lag_s,
                     len(self.recs), self.imu_latency_s)  # fmt: skip

    def with_params(self, params) -> "Problem":
        """The same recordings and weights with the parameters ``params``."""
        return Problem(self.scene, self.config, self.est, params, self.recs)

    def motions(self, theta) -> list:
        key = tuple(np.asarray(theta)[self.dynamic])
        if key != self._key:
            a = self.applied(theta)
            self._motions = [
                forward.simulate(
                    a.scene,
                    self.config,
                    r,
                    a.offsets_m,
                    a.servo_lag_s,
                    self.frame_nodes,
                    a.imu_latency_s,
                )
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
                forward.sensor_outputs(m, a.mounting_rpy_rad, gyro, accel),
                r,
            )
            for m, r, gyro, accel in zip(
                self.motions(theta), self.recs, a.gyro_bias_rad_s, a.accel_bias_m_s2, strict=True
            )
        ]

    def weighted(self, theta) -> list:
        """:meth:`errors` over their noise standard deviations (:func:`.forward.noise_std`)."""
        return [e / w for e, w in zip(self.errors(theta), self.weights, strict=True)]

    def __call__(self, theta) -> np.ndarray:
        try:
            w, broke = np.concatenate([e.ravel() for e in self.weighted(theta)]), ""
        except SimulationError as exc:
            w, broke = np.empty(0), f"the simulation broke ({exc})"
        return self._walled(theta, w, broke)

    def batch(self, thetas) -> list:
        """The residuals of several parameter vectors, in order (one after the other: the
        simulations they share are reused)."""
        return [self(t) for t in thetas]


def nominal_lag(est: EstimatorConfig, recs) -> float:
    """The lag to start from, s: the servos' response (the estimator's ``servo_lag_s``) for
    commanded lengths; none for read positions, which the strings follow as the servos turn."""
    return est.servo_lag_s if any(r.commanded for r in recs) else 0.0


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

    ``progress(simulations, cost)`` is called after every residual evaluation. Recordings
    simulated in more than one segment, started from the IMU (:func:`.shooting.anchored`),
    are fitted in two passes: the first segment of each alone (at least
    :data:`.shooting.FIRST_PASS_S`; it starts from the scene's known initial state), whose IMU
    mounting and gyro bias the later segments' starts then read the IMU with; then everything,
    from the first pass's optimum, then moved to the smooth minimum along the valley where the
    strings' stiffness and damping trade (:func:`.profile.strings_valley`).
    """
    lower = np.array([p.lower for p in params])
    steps = [p.step for p in params]
    segmented = two_passes(recs, forward.STEP_S)
    solve = solver(params, progress, max_nfev, SEGMENTED_FTOL if segmented else 1e-8)

    starts, dropped = latency_starts(params, est), []
    if segmented:
        first = [
            forward.window(r, max(r.segment_s, shooting.FIRST_PASS_S)) if r.segment_s else r
            for r in recs
        ]
        best, tried = _best_of(solve, Problem(scene, config, est, params, first), starts)
        theta0 = best.x
        a = apply(scene, config, params, theta0, nominal_lag(est, recs), len(recs))
        recs, dropped = _predictable(Problem(scene, config, est, params, anchored(recs, a)), theta0)
    problem = Problem(scene, config, est, params, recs)
    initial = [-e for e in problem.errors(np.zeros(len(params)))]
    if segmented:
        sol = solve(problem, theta0)
    else:
        sol, tried = _best_of(solve, problem, starts)
    strings = []
    if segmented:
        sol, strings = profile.strings_valley(solve, problem, sol, lower)
    final = [-e for e in problem.errors(sol.x)]
    sigma, corr, unresolved, separable, combos, valley, cov = statistics(problem, sol, lower, steps)
    spread, widened = np.ones(len(params)), {}
    if segmented:
        spread = profile.segment_spread(problem, sol.x, ~problem.dynamic, forward.STEP_S)
        widened = {p.name: float(r) for p, r in zip(params, spread, strict=True) if r > 1.0}
    along, lags = correlation_widening(problem, sol, cov, [len(e) for e in final])
    factors = np.array([along(e) for e in np.eye(len(params))])
    sigma = sigma * np.maximum(spread, factors)
    combos = [(c, value, s * along(c)) for c, value, s in combos]
    rms = {
        name: (stream_rms(initial, cols), stream_rms(final, cols)) for name, cols in STREAMS.items()
    }
    groups = {p.group for p in params}
    weighed = groups & set(weighing.SCALED) and not groups & set(BAR_GROUPS)
    sensitivity = weighing.bar_mass_sensitivity(problem, sol.x, sol.jac) if weighed else None
    return FitResult(
        params, sol.x, sigma, corr, unresolved, separable, combos, valley, final, initial, rms,
        float(sol.cost), int(sol.nfev), str(sol.message), scene, problem.servo_lag_s, dropped,
        widened, [(k, float(c)) for k, _, c in strings],
        residual_variance=problem.residual_variance(sol.fun, len(params)),
        mass_sensitivity=sensitivity,
        correlated={p.name: float(f) for p, f in zip(params, factors, strict=True) if f > 1.0},
        correlation_lags=lags,
        latency_starts=_latency_tries(params, starts, tried),
    )  # fmt: skip


def latency_starts(params, est: EstimatorConfig) -> list[np.ndarray]:
    """The parameter vectors the first solve starts from: the nominal alone, or, where the
    IMU's latency is fitted, one per half IMU period over its range, from none to the longest
    delay a sample may arrive with (``imu_max_delay_s``), the others at their nominal.

    The cost along the latency can have a basin at its lower bound, where a damping too high
    by a factor two or three makes up for the latency missing, beside the right one, and a
    start near the bound may end in it. The cost varies along the latency no faster than the
    IMU's signals, which it samples at ``imu_period_s``: no basin is narrower than a period,
    so starts half a period apart each have one within reach, and the lowest end is kept."""
    index = latency_index(params)
    if index is None:
        return [np.zeros(len(params))]
    spacing = 0.5 * est.imu_period_s
    grid = spacing * np.arange(int(np.floor(est.imu_max_delay_s / spacing + 1e-9)) + 1)
    starts = np.zeros((len(grid), len(params)))
    starts[:, index] = grid - params[index].nominal
    return list(starts)


def latency_index(params) -> int | None:
    """The index of the IMU latency among ``params``; None when it is not fitted."""
    return next((i for i, p in enumerate(params) if p.name == "imu_latency"), None)


def _best_of(solve, problem, starts):
    """The lowest-cost of ``solve(problem, start)`` over ``starts``, and every solution."""
    tried = [solve(problem, start) for start in starts]
    return min(tried, key=lambda sol: sol.cost), tried


def _latency_tries(params, starts, tried) -> list:
    """(start, cost, end) of the latency, s, for each of several starts (empty for one)."""
    if len(starts) < 2:
        return []
    i = latency_index(params)
    nominal = params[i].nominal
    pairs = zip(starts, tried, strict=True)
    return [(nominal + t[i], float(sol.cost), nominal + sol.x[i]) for t, sol in pairs]


def correlation_widening(problem: Problem, sol, cov, sizes):
    """``along(v)``: how much the residuals' correlation in time widens the sigma along the
    parameter direction ``v`` (:mod:`.correlated`; at least 1), and the bandwidth, samples;
    ``cov`` the linearised covariance :func:`statistics` gave."""
    s2 = problem.residual_variance(sol.fun, len(sol.x))
    hac, lags = correlated.sandwich(cov, s2, sol.jac, sol.fun, sizes, len(CHANNELS))
    return (lambda v: correlated.widening(cov, hac, v)), lags


def solver(params, progress, max_nfev: int, ftol: float, scaled: bool = False):
    """``solve(problem, theta0)``: the least-squares fit (:func:`.lsq.solve`) of a problem's
    residual (:class:`Problem` or one with its interface) from ``theta0`` within the bounds of
    ``params`` and with their finite-difference steps, ``progress(simulations, cost)`` after
    every evaluation.

    ``scaled``: the trust region measured in each parameter's step (scipy's ``x_scale``) rather
    than in the parameters' own units. The filter fit's differ by orders (rad, s, a log
    factor): unscaled, a first region as wide as a 0.02 rad start along the yaw let a 20 ms
    step of the latency in, every such step was refused, and the fit ended on ``xtol`` with
    the latency and the noise scale where they started."""
    lower = np.array([p.lower for p in params])
    upper = np.array([p.upper for p in params])
    steps = [p.step for p in params]
    options = {"x_scale": np.array(steps, float)} if scaled else {}

    def solve(problem, theta0):
        def reported(rs):
            if progress is not None:
                for r in rs:
                    progress(problem.simulations, 0.5 * float(r @ r))
            return rs

        return lsq.solve(
            lambda theta: reported([problem(theta)])[0],
            lambda thetas: reported(problem.batch(thetas)),
            theta0, steps, lower, upper, xtol=1e-10, ftol=ftol, max_nfev=max_nfev, **options,
        )  # fmt: skip

    return solve


def anchored(recs, applied) -> list:
    """``recs`` whose later segments' starts read the IMU (:func:`.shooting.anchored`) with the
    mounting and each recording's gyro bias of ``applied`` (:class:`.params.Applied`)."""
    return [
        replace(
            r,
            anchor_mounting_rpy_rad=tuple(applied.mounting_rpy_rad),
            anchor_gyro_bias_rad_s=tuple(g),
        )
        for r, g in zip(recs, applied.gyro_bias_rad_s, strict=True)
    ]


def two_passes(recs, dt_s: float) -> bool:
    """Whether :func:`fit` fits ``recs`` in two passes: one of them is simulated in more than
    one segment, started from the IMU (``dt_s``: the model's step, s)."""
    return any(r.segment_start == "imu" and len(shooting.edges_s(r, dt_s)) > 2 for r in recs)


def _predictable(problem: Problem, theta) -> tuple[list, list]:
    """The recordings of ``problem`` without the segments their prediction at ``theta`` does
    not follow (:func:`.shooting.predictable`), and those left out: (recording, start, end)."""
    recs, dropped = [], []
    for rec, err in zip(problem.recs, problem.weighted(theta), strict=True):
        kept, windows = shooting.predictable(rec, err, forward.STEP_S)
        recs.append(kept)
        dropped += [(rec.name, t0, t1) for t0, t1 in windows]
    return recs, dropped


def stream_rms(errors, cols) -> float:
    """RMS of the columns ``cols`` of every array of ``errors`` together."""
    return float(np.sqrt(np.mean(np.concatenate([e[:, cols] for e in errors]) ** 2)))


def statistics(problem: Problem, sol, lower, steps):
    """Sigmas, correlation, unresolved directions, separability, determined combinations, the
    direction of an undetermined common scale (or ``None``) and the linearised covariance
    (p, p), at the optimum ``sol`` (module docstring)."""
    J, r, theta, cost0 = sol.jac, sol.fun, sol.x, float(sol.cost)
    p = len(theta)
    s2 = problem.residual_variance(r, p)
    cov, unresolved, separable = uncertainty(J, s2, p)
    sigma, roughness = secant_sigmas(problem, theta, cov, separable, s2, cost0)
    members = scale_members(problem.params)
    valley, bend = None, np.zeros(p)
    if len(members):
        direction = scale_direction(problem, theta, members)
        rise, valley, bend = profile.scale_rise(
            problem, theta, direction, members, steps, lower, cost0
        )
        if 2.0 * rise >= profile.CHI2_95 * (s2 + 2.0 * roughness):
            valley, bend = None, np.zeros(p)
    if valley is None:
        cs = [c for c, _ in _determined(theta, unresolved, separable)]
    else:
        cov, unresolved, separable = uncertainty(J, s2, p, held=valley)
        sigma, _ = secant_sigmas(problem, theta, cov, separable, s2, cost0)
        cs = []
        for i in members[1:]:
            # the member against the bar's, in the proportion the valley moves them
            c = np.zeros(p)
            c[i], c[members[0]] = 1.0, -valley[i] / valley[members[0]]
            cs.append(c)
    combos = [
        (c, float(c @ theta), float(np.hypot(secant, c @ bend)))
        for c in cs
        for secant in [profile.secant_sigma(problem, theta, cov, c, s2, cost0)[0]]
    ]
    return (*_scaled(cov, sigma, separable), unresolved, separable, combos, valley, cov)


def scale_members(params) -> np.ndarray:
    """Indices of the parameters of :data:`SCALE_GROUPS`, a bar's first, when a group of
    :data:`BAR_GROUPS` is among them (else empty)."""
    groups = [p.group for p in params]
    if not any(g in BAR_GROUPS for g in groups):
        return np.zeros(0, int)
    idx = [i for i, g in enumerate(groups) if g in SCALE_GROUPS]
    return np.array(sorted(idx, key=lambda i: groups[i] not in BAR_GROUPS))


def scale_direction(problem: Problem, theta, members) -> np.ndarray:
    """Log factors, shape (p,), that scale every bar with its wheel by one unit: the bars'
    mass moves by ``(m_bar + m_wheel) / m_bar`` (the wheels' mass is kept), the other members
    (inertias, stiffness, damping) by one."""
    u = np.zeros(len(theta))
    u[members] = 1.0
    for i in members:
        if problem.params[i].group == "bar-mass":
            m = np.array([b.mass for b in problem.scene.bars]) * np.exp(theta[i])
            wheel = np.array([0.0 if b.wheel is None else b.wheel.mass for b in problem.scene.bars])
            u[i] = float(np.mean((m + wheel) / m))
    return u


def secant_sigmas(problem: Problem, theta, cov, separable, s2: float, cost0: float):
    """Linearised sigmas, with those of the separable parameters that need a simulation
    replaced by :func:`.profile.secant_sigma`; and the largest roughness met (cost units).
    The others' profiles hold the loose parameters (:func:`held_loose`)."""
    sigma = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    loose = sigma >= DETERMINED_SIGMA
    held = held_loose(cov, loose)
    roughness = 0.0
    for i in np.flatnonzero(separable & problem.dynamic):
        e = np.zeros(len(theta))
        e[i] = 1.0
        along = cov if loose[i] else held
        sigma[i], rough = profile.secant_sigma(problem, theta, along, e, s2, cost0)
        roughness = max(roughness, rough)
    return sigma, roughness


def held_loose(cov, loose):
    """``cov`` (p, p) of the other parameters with the ``loose`` ones (mask, shape (p,): a
    linearised sigma of :data:`DETERMINED_SIGMA` or more) held at the optimum: the Schur
    complement. A profile moves its parameter along ``cov``'s column, every correlated one by
    its share of its own sigma; a loose one's is a factor e or more (a flat likelihood: the node
    noise on a log that does not fix it), so each mounting profile stepped the noise by factors
    of 1e30 and beyond, broke the filter, and left the mounting undetermined with it."""
    if not loose.any():
        return cov
    gain = cov[:, loose] @ np.linalg.pinv(cov[np.ix_(loose, loose)])
    held = cov - gain @ cov[loose, :]
    held[loose, :], held[:, loose] = 0.0, 0.0
    return held


def _scaled(cov, sigma, separable):
    """Sigmas (``inf`` where not separable) and correlation of ``cov`` with ``sigma``."""
    lin = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = np.nan_to_num(cov / np.outer(lin, lin))
    sigma = np.where(separable, sigma, np.inf)
    return sigma, corr


def uncertainty(J: np.ndarray, s2: float, p: int, held=None):
    """Linearised covariance ``s^2 (J^T J)^+`` (shape (p, p)), unresolved directions and
    separability from the Jacobian ``J`` (n, p) of the weighted residuals at the optimum, whose
    noise variance is ``s2`` (:meth:`WalledResiduals.residual_variance`); ``held`` (unit
    vector, shape (p,)): a direction known to be unresolved, left out of the covariance (the
    others given it) and added to the unresolved ones."""
    B = np.eye(p) if held is None else np.linalg.svd(held[None, :])[2][1:].T
    JB = J @ B
    norms = np.linalg.norm(JB, axis=0)
    norms[norms == 0.0] = 1.0
    _, sv, Vt = np.linalg.svd(JB / norms, full_matrices=False)
    resolved = sv > RCOND * sv[0]
    unresolved = [B @ Vt[i] for i in np.flatnonzero(~resolved)]
    unresolved += [] if held is None else [held]
    separable = np.ones(p, bool)
    for v in unresolved:
        separable &= np.abs(v) <= INVOLVED
    # pseudo-inverse over the resolved directions: the unresolved ones would swamp the rest
    inv = (Vt[resolved].T / sv[resolved] ** 2) @ Vt[resolved]
    cov = B @ (s2 * inv / np.outer(norms, norms)) @ B.T
    return cov, unresolved, separable


def _determined(theta, unresolved, separable) -> list[tuple[np.ndarray, float]]:
    """Unit combinations ``c`` of the non-separable parameters that the data do determine, with
    their values ``c . theta`` (relative/absolute units of the parameters involved)."""
    idx = np.flatnonzero(~separable)
    if not len(idx):
        return []
    null = np.array([v[idx] for v in unresolved])
    _, sv, Vt = np.linalg.svd(null, full_matrices=True)
    rank = int(np.sum(sv > 1e-9))
    out = []
    for c_sub in Vt[rank:]:
        c = np.zeros(len(theta))
        c[idx] = c_sub
        out.append((c, float(c @ theta)))
    return out
