"""Sigmas and separability read off the cost itself, not only its Jacobian.

On the rig's fixed-step model the cost is rough: where a string goes slack a step earlier or
later it jumps by about 1 (cost units, half the weighted sum of squares) between neighbouring
parameter values, which is as much as the statistical rise over one or two sigmas of the
strings' stiffness and damping. The Jacobian at the optimum then reads the curvature of one
jump rather than of the cost, and the optimum lands anywhere in a band where the cost's smooth
rise is below its jumps; the residuals themselves stay white (their autocorrelation is at most
about 0.1 at every lag, reports/identification-history.md), so a sandwich or effective-sample-size
correction of ``s^2 (J^T J)^-1`` would not see it. Two checks on the cost do:

* :func:`secant_sigma`: the cost sampled along a parameter's linearised profile direction (the
  other parameters following their regression on it) at :data:`PROFILE_STEPS` of its
  linearised sigma, fitted with a parabola: its curvature ``a`` (cost units per unit squared)
  and the scatter ``eps`` of the samples about it (the roughness). The 1-sigma is
  ``sqrt((s^2 + 2 eps) / a)``: one sigma is where the smooth cost has risen by the noise's
  ``s^2 / 2`` plus the roughness ``eps``. Where the samples are not convex (jumps larger than
  the rise within those steps) they are taken again :data:`PROFILE_WIDER` times as far out.
* :func:`scale_rise`: scaling every mass, inertia, stiffness and damping by one factor leaves the
  D-bar's motion almost unchanged; the Jacobian does not show it (the valley is narrow and bent
  by the wheels' mass, which is kept). The cost is re-minimised with that common factor held
  :data:`SCALE_STEP` below and above the optimum (starting where the bars' mass moves so that
  bar and wheel together scale by it); if it rises by less than the chi-square
  significance (:data:`CHI2_95`, in units of ``s^2 + 2 eps``) on either side, the scale is not
  determined by the data, and the line through the two re-fitted optima is the direction that
  is not. A combination across that line still changes along the bent valley: its change
  ``c . bend`` within the scale tested is added to its sigma (in quadrature).

The same roughness stops the local solver wherever it starts along the valley where the strings'
stiffness and damping trade; :func:`strings_valley` solves the fit again along it and takes the
smooth minimum of the optima it reaches.
"""

from collections.abc import Callable
from contextlib import contextmanager
from contextvars import ContextVar
from itertools import count

import numpy as np

from gyrohost.ident import lsq, shooting

PROFILE_STEPS = (-6.0, -4.5, -3.0, -1.5, 1.5, 3.0, 4.5, 6.0)
"""Where the cost is sampled along a profile direction, in linearised sigmas."""
PROFILE_WIDER = 4.0
"""How much farther out the profile is sampled again where the samples at :data:`PROFILE_STEPS`
are not convex: the filter fit's cost jumps by tens of units within a few sigmas of J3 (gates
and slack kinks crossed a step earlier or later), while its smooth rise at 24 sigmas is some 300
units (``s^2`` about 1), so the wider samples read the curvature under the jumps and count the
jumps as roughness in the sigma."""
VALLEY_STEPS = (-2.0, -1.0, 1.0, 2.0)
"""Where a fit in segments is solved again along the strings' valley, in :data:`VALLEY_STEP`."""
VALLEY_REACH = 4.0
"""The farthest start along the valley, in :data:`VALLEY_STEP` (log factors 0.48 and 0.8)."""
VALLEY_STEP = np.array([0.12, 0.2])
"""One valley step in the strings' log stiffness and log damping: along the valley where the
two trade on the D-bar's preset (solved again from there, the fit stays within a few percent of
its start, at costs within tens of units; along the major axis of their linearised covariance
it slides back towards the start instead) and about the spacing of the local optima along it
(docs/identification.md)."""
LINE_SIGMAS = np.linspace(-3.0, 3.0, 13)
"""Where the cost is sampled along one parameter before a fit starts (:func:`line_start`), in
the sigmas the stage before gave it: +-3 of them, half a sigma apart."""
LINE_REACH = 6.0
"""How far out, in those sigmas, the samples go on while the lowest is the outermost."""
SCALE_STEP = 0.2
"""Log factor of the common scale tested: +-20 % (the spread of the unmeasured parameters)."""
CHI2_95 = 3.841
"""Chi-square, one degree of freedom, 95 %: the rise of ``2 cost / s^2`` that is significant."""
SCALE_EVALUATIONS = 12
"""Residual evaluations of each re-minimisation with the scale held."""


_observer: ContextVar[Callable[[str, int, int | None], None] | None] = ContextVar(
    "profile_observer", default=None
)


@contextmanager
def observing(callback: Callable[[str, int, int | None], None]):
    """Within the block, ``callback(step, done, total)`` is called after every evaluation of
    the cost by :func:`secant_sigma` and :func:`scale_rise` (the statistics after a fit, which
    take about as long as the fit): ``step`` is ``"profile"`` (``"profile wider"`` where it is
    sampled again farther out) or ``"scale below"`` / ``"scale above"``, ``done`` the
    evaluations of that step so far (1 starts a new one), ``total`` its number of evaluations
    (``None``: open-ended, a re-minimisation)."""
    token = _observer.set(callback)
    try:
        yield
    finally:
        _observer.reset(token)


def _notify(step: str, done: int, total: int | None) -> None:
    callback = _observer.get()
    if callback is not None:
        callback(step, done, total)


def secant_sigma(problem, theta, cov, c, s2: float, cost0: float) -> tuple[float, float]:
    """1-sigma of the combination ``c . theta`` from the cost along its profile direction.

    Parameters
    ----------
    problem : callable
        Weighted residual of a parameter vector (:class:`.fit.Problem`).
    theta : ndarray, shape (p,)
        The optimum.
    cov : ndarray, shape (p, p)
        Linearised covariance (``s^2`` included).
    c : ndarray, shape (p,)
        The combination (a unit vector for one parameter).
    s2 : float
        Residual variance per degree of freedom (weighted units).
    cost0 : float
        Cost at ``theta``.

    Returns
    -------
    sigma : float
        ``inf`` where the sampled cost is not convex, at :data:`PROFILE_STEPS` nor
        :data:`PROFILE_WIDER` times as far out, or where a sample broke the model.
    roughness : float
        Standard deviation of the samples about their parabola (cost units).
    """
    sd = float(np.sqrt(c @ cov @ c))
    direction = cov @ c / sd  # moves c . theta by one linearised sigma per unit
    for widen, step in ((1.0, "profile"), (PROFILE_WIDER, "profile wider")):
        curvature, roughness, broke = _parabola(
            problem, theta, direction * widen, sd * widen, cost0, step
        )
        if broke:
            break
        if curvature > 0.0:
            return float(np.sqrt((s2 + 2.0 * roughness) / curvature)), roughness
    return np.inf, roughness


def _parabola(problem, theta, direction, unit: float, cost0: float, step: str):
    """Curvature (cost units per unit of ``c . theta`` squared) and roughness (cost units) of
    the cost sampled at :data:`PROFILE_STEPS` along ``direction`` (shape (p,), one step moves
    ``c . theta`` by ``unit``) and at ``theta`` itself; and whether a sample broke the
    problem's model (its ``failures`` grew: the filter fit's wall of residuals, whose rise
    is the wall's and not the data's)."""
    broken = len(problem.failures)
    t = np.append(PROFILE_STEPS, 0.0)
    rise = np.zeros(len(t))
    for j, r in enumerate(problem.batch([theta + k * direction for k in PROFILE_STEPS])):
        rise[j] = 0.5 * float(r @ r) - cost0
        _notify(step, j + 1, len(PROFILE_STEPS))
    x = t * unit
    A = np.column_stack([np.ones_like(x), x, 0.5 * x**2])
    coef = np.linalg.lstsq(A, rise, rcond=None)[0]
    roughness = float(np.sqrt(np.sum((rise - A @ coef) ** 2) / (len(x) - 3)))
    return float(coef[2]), roughness, len(problem.failures) > broken


def held_basis(p: int, members: np.ndarray) -> np.ndarray:
    """Orthonormal basis, shape (p, p - 1), of the parameter vectors that keep the sum over
    ``members`` (indices) fixed: the members' mixed axes first, then every other parameter as
    its own axis (moving a sensor parameter alone needs no new simulation)."""
    k = len(members)
    _, _, Vt = np.linalg.svd(np.ones((1, k)))
    B = np.zeros((p, p - 1))
    B[np.ix_(members, np.arange(k - 1))] = Vt[1:].T
    B[np.setdiff1d(np.arange(p), members), np.arange(k - 1, p - 1)] = 1.0
    return B


def scale_rise(problem, theta, direction, members, steps, lower, cost0: float):
    """The smaller rise of the cost with the common scale moved ``SCALE_STEP`` along
    ``direction`` (shape (p,): log factors per unit of scale) below and above the optimum and
    the other combinations of ``members`` (indices) and parameters re-fitted, in cost units;
    the unit direction from the one re-fitted optimum to the other (the valley the scale
    moves along); and the bend of the valley, shape (p,): the re-fitted optima's mean less
    ``theta`` (a combination across the straight valley still changes by ``c . bend``
    within the scale tested).

    ``steps``, ``lower`` (p,): the parameters' finite-difference steps and lower bounds."""
    p, k = len(theta), len(members)
    B = held_basis(p, members)
    others = np.setdiff1d(np.arange(p), members)
    steps, lower = np.asarray(steps, float), np.asarray(lower, float)
    z_steps = np.append(np.full(k - 1, steps[members].max()), steps[others])
    rises, ends = [], []
    for h, label in ((-SCALE_STEP, "scale below"), (SCALE_STEP, "scale above")):
        start = theta + h * np.asarray(direction)
        z_lower = np.append(np.full(k - 1, -np.inf), lower[others] - start[others])
        calls = count(1)

        def held(zs, s=start, label=label, calls=calls):
            rs = problem.batch([s + B @ z for z in zs])
            for _ in rs:
                _notify(label, next(calls), None)  # the Jacobian's evaluations count too
            return rs

        sol = lsq.solve(
            lambda z, held=held: held([z])[0],
            held,
            np.maximum(np.zeros(p - 1), z_lower + 1e-9),
            z_steps,
            z_lower,
            max_nfev=SCALE_EVALUATIONS,
        )
        rises.append(float(sol.cost) - cost0)
        ends.append(start + B @ sol.x)
    valley = ends[1] - ends[0]
    return min(rises), valley / np.linalg.norm(valley), 0.5 * (ends[0] + ends[1]) - theta


def segment_spread(problem, theta, output: np.ndarray, dt_s: float) -> np.ndarray:
    """How far the segments of a fit in segments disagree about each output parameter (the
    mounting and the biases: ``output``, bool of shape (p,)), beyond their own noise: the Birge
    ratio ``sqrt(sum_i a_i (x_i - xbar)^2 / (n - 1))`` of the segments' own optima ``x_i``
    (each segment's weighted sum of squares, the other parameters held, as a parabola through
    ``theta`` and ``theta +- step``: curvature ``a_i``, ``1 / a_i`` its variance) about their
    weighted mean ``xbar``; at least 1, and 1 for the other parameters or fewer than 3
    segments. Shape (p,).

    Each later segment starts from the IMU's attitude and rate read with the first pass's
    mounting (:func:`.shooting.anchored`); what that start misses (the shape's own motion) each
    segment's mounting absorbs differently, by more than its noise allows (the yaw by 1e-3 rad
    between segments whose own sigma is 2e-4, reports/identification-history.md), which the
    sigmas from the whole cost do not see.
    """
    segments = [
        np.searchsorted(shooting.edges_s(r, dt_s), r.t_imu_s, "right") - 1 for r in problem.recs
    ]
    ratio = np.ones(len(theta))
    mid = np.concatenate(_segment_sums(problem.weighted(theta), segments))
    for i in np.flatnonzero(output):
        h = problem.params[i].step
        sums = []
        for d in (-h, h):
            t = np.array(theta, float)
            t[i] += d
            sums.append(np.concatenate(_segment_sums(problem.weighted(t), segments)))
        lo, hi = sums
        a = (lo + hi - 2.0 * mid) / (2.0 * h * h)
        keep = a > 0.0
        if np.count_nonzero(keep) < 3:
            continue
        x, a = -(hi - lo)[keep] / (2.0 * h) / (2.0 * a[keep]), a[keep]
        chi2 = float(np.sum(a * (x - np.sum(a * x) / np.sum(a)) ** 2))
        ratio[i] = max(1.0, np.sqrt(chi2 / (len(x) - 1)))
    return ratio


def _segment_sums(weighted, segments) -> list[np.ndarray]:
    """Per recording, each segment's weighted sum of squares, shape (segments,)."""
    return [
        np.array([np.sum(w[seg == k] ** 2) for k in range(seg.max() + 1)])
        for w, seg in zip(weighted, segments, strict=True)
    ]


def strings_valley(solve, problem, sol, lower):
    """The fit ``sol`` moved to the smooth minimum of the valley where the strings' stiffness and
    damping trade (correlation about +0.9).

    Along that valley the cost is rough and the local solver stops near wherever it starts,
    at optima some 0.2 apart in log damping whose costs differ by tens of units. The fit is
    solved again from :data:`VALLEY_STEPS` of :data:`VALLEY_STEP`, and one step further out
    while the lowest optimum is the outermost on its side (up to :data:`VALLEY_REACH` steps); a
    parabola is fitted to the costs of the lowest optimum and up to two neighbours either side
    against their offsets along the step, and the fit is solved once more from the optima
    interpolated at its vertex (the lowest optimum's offset where it is not convex).

    Parameters
    ----------
    solve : callable
        ``solve(problem, theta0) -> scipy.optimize.OptimizeResult`` (with ``x`` and ``cost``):
        the fit's local solver.
    problem : .fit.Problem
    sol : OptimizeResult
        The fit's optimum.
    lower : ndarray, shape (p,)
        The parameters' lower bounds; a start below one is not tried.

    Returns
    -------
    sol : OptimizeResult
        The fit from the vertex (``sol`` itself without both strings' parameters).
    points : list of (offset, theta, cost)
        Every optimum along the valley, ``sol``'s at offset 0, sorted by offset (valley steps).
    """
    names = [p.name for p in problem.params]
    if "stiffness" not in names or "damping" not in names:
        return sol, []
    idx = [names.index("stiffness"), names.index("damping")]

    def solved_from(k: float):
        start = np.array(sol.x, float)
        start[idx] += k * VALLEY_STEP
        return solve(problem, start) if np.all(start >= lower) else None

    tried = {0.0: sol} | {k: solved_from(k) for k in VALLEY_STEPS}
    while True:
        points = _valley_points(tried.values(), sol.x[idx], idx)
        lowest = int(np.argmin([c for _, _, c in points]))
        if 0 < lowest < len(points) - 1:
            break
        k = min(tried) - 1.0 if lowest == 0 else max(tried) + 1.0
        if abs(k) > VALLEY_REACH:
            break
        tried[k] = solved_from(k)
        if tried[k] is None:
            break
    offsets, thetas, costs = (np.array(v) for v in zip(*points, strict=True))
    vertex = lowest_vertex(offsets, costs)  # between two neighbouring optima: interpolated
    start = np.array([np.interp(vertex, offsets, column) for column in thetas.T])
    return solve(problem, start), points


def lowest_vertex(offsets: np.ndarray, costs: np.ndarray) -> float:
    """Where a parabola through the lowest of ``costs`` (at increasing ``offsets``) and up to
    two neighbours either side has its vertex, within them; the lowest's offset where they are
    not convex."""
    lowest = int(np.argmin(costs))
    lo, hi = max(lowest - 2, 0), lowest + 3
    offsets, costs = np.asarray(offsets[lo:hi], float), np.asarray(costs[lo:hi], float)
    vertex = float(offsets[lowest - lo])
    if len(offsets) >= 3:
        a, b, _ = np.polyfit(offsets, costs, 2)
        if a > 0.0:
            vertex = float(np.clip(-b / (2.0 * a), offsets[0], offsets[-1]))
    return vertex


def line_start(problem, theta, i: int, sigma: float) -> tuple[np.ndarray, list]:
    """``theta`` with parameter ``i`` moved to the smooth minimum of the cost along it within
    ``+-3 sigma`` (:data:`LINE_SIGMAS`), and the samples (offset, cost).

    The filter's likelihood is smooth only near the rig's value of the IMU's yaw: a degree or
    two away its linearisation breaks at moments of the run and the cost jumps by hundreds
    (reports/identification-heldout.md), and over a finite-difference step it is rough by some
    ten units everywhere (gates and slack kinks crossed a sample earlier). A local solve started
    out there refuses every step and stops where it began; started from the vertex of the
    lowest samples along the line (:func:`lowest_vertex`), it is in the smooth basin. While the
    lowest sample is the outermost, the line goes on by as many samples that side, up to
    :data:`LINE_REACH` sigmas."""
    spacing = LINE_SIGMAS[1] - LINE_SIGMAS[0]
    samples = dict(_line_costs(problem, theta, i, LINE_SIGMAS * sigma))
    while True:
        offsets = np.array(sorted(samples))
        lowest = int(np.argmin([samples[o] for o in offsets]))
        side = -1.0 if lowest == 0 else 1.0 if lowest == len(offsets) - 1 else 0.0
        edge = offsets[lowest] / sigma
        if side == 0.0 or abs(edge) + spacing > LINE_REACH + 1e-9:
            break
        more = edge + side * spacing * np.arange(1, len(LINE_SIGMAS) // 2 + 1)
        more = more[np.abs(more) <= LINE_REACH + 1e-9]
        samples.update(_line_costs(problem, theta, i, more * sigma))
    costs = np.array([samples[o] for o in offsets])
    start = np.array(theta, float)
    start[i] += lowest_vertex(offsets, costs)
    return start, list(zip(offsets.tolist(), costs.tolist(), strict=True))


def _line_costs(problem, theta, i: int, offsets) -> list[tuple[float, float]]:
    """(offset, cost) of ``theta`` with parameter ``i`` moved by each of ``offsets``."""
    thetas = []
    for o in offsets:
        t = np.array(theta, float)
        t[i] += o
        thetas.append(t)
    return [
        (float(o), 0.5 * float(r @ r)) for o, r in zip(offsets, problem.batch(thetas), strict=True)
    ]


def _valley_points(optima, origin, idx) -> list[tuple]:
    """(offset along :data:`VALLEY_STEP` from ``origin``, theta, cost) of each optimum solved
    (``None``: not tried), sorted by offset."""
    step2 = float(VALLEY_STEP @ VALLEY_STEP)
    return sorted(
        (
            (float((o.x[idx] - origin) @ VALLEY_STEP) / step2, o.x, float(o.cost))
            for o in optima
            if o is not None
        ),
        key=lambda point: point[0],
    )
