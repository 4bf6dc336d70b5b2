"""The fit's statistics on residual functions whose answer is known in closed form: sigmas read
off the cost (roughness counted), the common scale of masses and stiffnesses tested by
re-minimising, and the report printing what the data cannot separate."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import least_squares

from gyrohost.ident import profile
from gyrohost.ident.fit import (
    FAILED_RESIDUAL,
    FitResult,
    WalledResiduals,
    statistics,
    uncertainty,
)
from gyrohost.ident.params import Param
from gyrohost.ident.report import apply_result, read_identified, report_lines

RNG = np.random.default_rng(7)
T = np.linspace(0.0, 1.0, 400)
NOISE = RNG.normal(size=(2, len(T)))


class Problem(WalledResiduals):
    """Weighted residuals of the four log factors J3, bar mass, stiffness, damping and one
    sensor parameter: the motion depends on J3, stiffness and damping relative to the bar mass
    (the scale symmetry) plus ``pin`` times the bar mass on its own (the wheels' mass, or a
    weighed bar), with unit noise; ``rough`` adds a cost jump pattern (the slack crossings)."""

    def __init__(self, truth, pin=0.0, rough=0.0):
        self.truth, self.pin, self.rough = np.asarray(truth), pin, rough
        names = (("J3", "J3"), ("bar_mass", "bar-mass"), ("stiffness", "stiffness"))
        self.params = [Param(n, g, True, 1.0, "-") for n, g in names]
        self.params += [Param("damping", "damping", True, 1.0, "-")]
        self.params += [Param("mounting.roll", "mounting", False, 0.0, "rad")]
        self.dynamic = np.array([True] * 4 + [False])
        self.scene = SimpleNamespace(bars=[SimpleNamespace(mass=1.0, wheel=None)])
        self.failures = []  # its model never breaks

    def signals(self, theta):
        j, m, k, c, roll = theta
        a, b, d = j - m, k - m, c - m
        return np.concatenate(
            [
                30 * a * np.sin(9 * T) + 5 * b * np.cos(4 * T) + 3 * d * T,
                20 * roll * np.ones_like(T) + self.pin * m * T**2,
            ]
        )

    def __call__(self, theta):
        theta = np.asarray(theta, float)
        r = self.signals(theta) - self.signals(self.truth) - NOISE.ravel()
        if self.rough:
            # a residual oscillating faster than any step in the stiffness: a rough cost
            r = np.append(r, self.rough * np.sin(5000 * theta[2]))
        return r

    def batch(self, thetas):
        return [self(t) for t in thetas]


def solve(problem):
    steps = [0.03] * 5
    sol = least_squares(problem, np.zeros(5), diff_step=steps, xtol=1e-12)
    lower = [-np.inf] * 5
    return sol, statistics(problem, sol, lower, steps)


def linear_sigma(problem, sol):
    r, J = sol.fun, sol.jac
    s2 = r @ r / (len(r) - 5)
    return np.sqrt(np.diag(s2 * np.linalg.pinv(J.T @ J)))


def test_a_pinned_scale_gives_every_parameter_with_its_linear_sigma():
    """Weighed bars (a strong pin): everything separable; on a smooth, linear residual the
    sigmas read off the cost equal the closed form s^2 (J^T J)^-1."""
    problem = Problem([0.2, -0.2, 0.1, -0.3, 0.01], pin=200.0)
    sol, (sigma, corr, unresolved, separable, combos, valley, _) = solve(problem)
    assert valley is None and all(separable) and not unresolved and not combos
    np.testing.assert_allclose(sigma, linear_sigma(problem, sol), rtol=0.02)
    assert sol.x[1] == pytest.approx(-0.2, abs=4 * sigma[1])


def test_roughness_widens_the_sigma_of_the_parameter_it_hits():
    smooth = Problem([0.2, -0.2, 0.1, -0.3, 0.01], pin=200.0)
    rough = Problem([0.2, -0.2, 0.1, -0.3, 0.01], pin=200.0, rough=1.5)
    sigma_smooth = solve(smooth)[1][0]
    sigma_rough = solve(rough)[1][0]
    assert sigma_rough[2] > 1.5 * sigma_smooth[2]  # stiffness: the rough one
    assert sigma_rough[0] == pytest.approx(sigma_smooth[0], rel=0.1)  # J3: untouched


class Dropped:
    """One parameter with a smooth 1-sigma of 0.01 (unit noise) whose cost drops by ``drop``
    units beyond -5 sigmas, as the filter fit's does where a gate or a slack kink is crossed a
    step earlier."""

    def __init__(self, drop: float):
        self.jump = np.sqrt(2.0 * drop)
        self.failures = []

    def __call__(self, theta):
        x = float(theta[0])
        return np.array([x / 0.01, 0.0 if x < -0.05 else self.jump])

    def batch(self, thetas):
        return [self(t) for t in thetas]


@pytest.mark.parametrize("drop", [0.0, 40.5])
def test_a_cost_not_convex_within_six_sigmas_is_sampled_again_farther_out(drop):
    """A drop larger than the smooth rise within the profile's steps leaves those samples
    concave; four times as far out the rise dominates and the drop counts as roughness."""
    problem, theta = Dropped(drop), np.zeros(1)
    cost0 = 0.5 * float(problem(theta) @ problem(theta))
    steps = []
    with profile.observing(lambda step, *_: steps.append(step)):
        sigma, rough = profile.secant_sigma(
            problem, theta, np.eye(1) * 1e-4, np.ones(1), 1.0, cost0
        )
    wider = "profile wider" in steps
    assert wider == (drop > 0.0), set(steps)
    assert sigma == pytest.approx(0.01 * np.sqrt(1.0 + 2.0 * rough), rel=0.02)
    assert (rough > 10.0) if wider else (rough < 1e-9)


class Walled(Dropped):
    """:class:`Dropped` whose model breaks beyond 0.1 (a filter that diverges): the
    residuals there are a wall, and the break is counted as the filter fit counts it."""

    def __call__(self, theta):
        if abs(float(theta[0])) > 0.1:
            self.failures.append(f"broke at {float(theta[0]):.3g}")
            return np.full(2, 1e3)
        return super().__call__(theta)


def test_a_profile_that_breaks_the_model_gives_no_sigma():
    """The wider samples reach 0.24, where the model breaks: the wall's rise is not the
    data's (read as a parabola it gives 0.16 here), so no sigma is read off it."""
    problem, theta = Walled(40.5), np.zeros(1)
    cost0 = 0.5 * float(problem(theta) @ problem(theta))
    sigma, _ = profile.secant_sigma(problem, theta, np.eye(1) * 1e-4, np.ones(1), 1.0, cost0)
    assert problem.failures and sigma == np.inf


def test_an_unpinned_scale_is_reported_with_the_combinations_that_are_determined():
    """Bars not weighed (a pin within the noise over +-20 %): the scale is flagged, the four factors
    are not separable, their combinations along the valley are determined and within their
    sigmas of the truth's; the report prints no number for the bar mass."""
    truth = np.array([0.26, -0.22, 0.22, -0.36, 0.01])
    problem = Problem(truth, pin=0.5)
    sol, (sigma, corr, unresolved, separable, combos, valley, _) = solve(problem)
    assert all(uncertainty(sol.jac, 1.0, 5)[2])  # the singular values alone miss it
    assert valley is not None
    np.testing.assert_allclose(np.abs(valley[:4]), 0.5, atol=0.05)  # about the common factor
    assert list(separable) == [False] * 4 + [True]
    assert np.all(np.isinf(sigma[:4])) and np.isfinite(sigma[4])
    assert len(combos) == 3
    for c, value, s in combos:
        assert abs(value - c @ truth) < 3 * s
    result = FitResult(
        problem.params, sol.x, sigma, corr, unresolved, separable, combos, valley,
        [], [], {}, float(sol.cost), int(sol.nfev), "", None, 0.0,
    )  # fmt: skip
    lines = report_lines(result)
    bar = next(line for line in lines if line.startswith("bar_mass"))
    assert "not separable" in bar
    assert sum(line.startswith("determined:") for line in lines) == 3
    assert any("common scale" in line for line in lines)
    assert not any("valley" in line for line in lines)  # a fit in one segment has none
    header = "\n".join(f"# {line}" for line in ["Identified by gyrotens identify", *lines])
    (name,) = read_identified(header)  # the not separable left out, no other line taken
    assert name == problem.params[4].name
    value, one_sigma = read_identified(header)[name]
    assert value == pytest.approx(result.value(4), rel=1e-5)
    assert one_sigma == pytest.approx(result.value_sigma(4), rel=5e-3)
    walked = replace(result, strings_valley=[(-1.02, 6513.0), (0.0, 6582.2), (0.83, 6651.2)])
    line = next(line for line in report_lines(walked) if line.startswith("strings' valley"))
    assert "stiffness x1.127 and damping x1.221" in line
    assert "-1.02: 6513.0, +0.00: 6582.2, +0.83: 6651.2" in line


def test_the_identified_scene_keeps_the_bars_nominal_along_an_undetermined_scale():
    """The estimate moved along the valley to the nominal bar mass: the factors' ratios (the
    motion) are kept."""
    from gyrohost.config import load_rig_config
    from gyrohost.resources import resolve
    from gyrotensegrity import load_scene

    config = load_rig_config(resolve("config", "sim-rig"))
    scene = load_scene(config.scene_path)
    problem = Problem(np.zeros(5))
    params = [replace(p, nominal=1.0) for p in problem.params]
    theta = np.array([0.3, 0.1, 0.2, -0.1, 0.0])
    valley = np.array([0.5, 0.5, 0.5, 0.5, 0.0])
    separable = np.array([False] * 4 + [True])
    result = FitResult(
        params, theta, np.zeros(5), np.eye(5), [valley], separable, [], valley,
        [], [], {}, 0.0, 0, "", scene, 0.05,
    )  # fmt: skip
    applied = apply_result(result, config).scene
    assert [b.mass for b in applied.bars] == pytest.approx([b.mass for b in scene.bars])
    k = applied.strings[0].stiffness / scene.strings[0].stiffness
    assert k == pytest.approx(np.exp(0.2 - 0.1))


def test_parameters_not_determined_keep_their_nominal_and_are_named():
    """A separable parameter whose 1-sigma is infinite (no minimum) or a factor e and more
    (what a log past the roll-over, or one the rig could not record in real time, gives) is
    reported as undetermined and left at its nominal in the scene."""
    from gyrohost.config import load_rig_config
    from gyrohost.ident.report import undetermined
    from gyrohost.resources import resolve
    from gyrotensegrity import load_scene

    config = load_rig_config(resolve("config", "sim-rig"))
    scene = load_scene(config.scene_path)
    params = [replace(p, nominal=1.0) for p in Problem(np.zeros(5)).params]
    theta = np.array([0.1, 0.2, 9.0, 2.5, -0.1])  # the third and fourth where the fit ended
    sigma = np.array([0.01, 0.02, np.inf, 1.0, 0.03])
    result = FitResult(
        params, theta, sigma, np.eye(5), [], np.ones(5, bool), [], None,
        [], [], {}, 0.0, 0, "", scene, 0.05,
    )  # fmt: skip
    assert list(result.determined) == [True, True, False, False, True]
    assert undetermined(result) == [params[2].name, params[3].name]
    lines = report_lines(result)
    for p in params[2:4]:
        assert "undetermined" in next(line for line in lines if line.startswith(p.name))
    header = "\n".join(f"# {line}" for line in lines)
    assert set(read_identified(header)) == {params[i].name for i in (0, 1, 4)}
    kept = apply_result(replace(result, theta=np.where(result.determined, theta, 0.0)), config)
    np.testing.assert_equal(apply_result(result, config).scene.to_dict(), kept.scene.to_dict())
    assert not any("residual variance" in line for line in lines)  # none computed
    told = report_lines(replace(result, residual_variance=9.24))
    assert "residual variance per degree of freedom 9.24 (near 1 where" in "\n".join(told)


def test_held_direction_leaves_the_covariance():
    J = RNG.normal(size=(300, 3))
    u = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    cov, unresolved, separable = uncertainty(J, 1.0, 3, held=u)
    assert u @ cov @ u == pytest.approx(0.0, abs=1e-12)
    assert list(separable) == [False, False, True]
    assert cov[2, 2] > 0 and len(unresolved) == 1


def test_scale_rise_is_zero_along_an_exact_symmetry():
    problem = Problem([0.2, -0.2, 0.1, -0.3, 0.01], pin=0.0)
    sol = least_squares(problem, np.zeros(5), diff_step=0.03)
    members = np.array([1, 0, 2, 3])
    direction = np.array([1.0, 1.0, 1.0, 1.0, 0.0])
    rise, valley, bend = profile.scale_rise(
        problem, sol.x, direction, members, [0.03] * 5, [-np.inf] * 5, float(sol.cost)
    )
    assert rise == pytest.approx(0.0, abs=1e-3)
    np.testing.assert_allclose(np.abs(valley[:4]), 0.5, atol=1e-3)
    np.testing.assert_allclose(bend, 0.0, atol=1e-3)  # a straight valley


def test_the_statistics_report_every_cost_evaluation_as_progress():
    """The sigmas' profiles and the scale test call the observer after every evaluation of the
    cost (none during the fit itself): four single-parameter profiles, the scale refits below
    and above, three combinations' profiles, each profile sampled at every step."""
    problem = Problem(np.array([0.26, -0.22, 0.22, -0.36, 0.01]), pin=0.5)
    sol = least_squares(problem, np.zeros(5), diff_step=[0.03] * 5, xtol=1e-12)
    calls = []
    with profile.observing(lambda *step: calls.append(step)):
        statistics(problem, sol, [-np.inf] * 5, [0.03] * 5)
    n = len(profile.PROFILE_STEPS)
    profiles = [c for c in calls if c[0] == "profile"]
    assert [done for _, done, _ in profiles] == list(range(1, n + 1)) * 7
    assert {total for *_, total in profiles} == {n}
    for side in ("scale below", "scale above"):
        refit = [done for step, done, total in calls if step == side and total is None]
        # the start and at least one Jacobian's four columns (the scale held: 4 of 5 free)
        assert len(refit) >= 1 + 4 and refit == list(range(1, len(refit) + 1))
    assert [c[0] for c in calls].index("scale below") == 4 * n  # after the four profiles
    seen = len(calls)
    statistics(problem, sol, [-np.inf] * 5, [0.03] * 5)  # outside the block: not observed
    assert len(calls) == seen


def test_the_identify_progress_line_shows_the_statistics_step():
    from io import StringIO

    from gyrohost.commands.identify import FitProgress

    stream = StringIO()
    stream.isatty = lambda: True
    bar = FitProgress(10, stream)
    bar(1, 2.5)
    for done in (1, 2):
        bar.statistics("profile", done, 8)
    bar.statistics("profile", 1, 8)
    bar.statistics("scale below", 5, None)
    bar.close()
    text = stream.getvalue()
    assert "cost 2.5" in text and "statistics: cost profile 1, evaluation 2/8" in text
    assert "cost profile 2, evaluation 1/8" in text
    assert "scale below refit, evaluation 5;    4 in all" in text


def test_off_a_terminal_the_identify_progress_is_a_line_every_ten_seconds_with_time_left():
    """A fit logged to a file shows it lives: one plain line per ``every_s`` of the clock, with
    the evaluations' budget and at most how long is left at the pace so far."""
    from io import StringIO

    from gyrohost.commands.identify import FitProgress

    now = [0.0]
    stream = StringIO()
    bar = FitProgress(100, stream, clock=lambda: now[0])
    for k in range(40):
        now[0] = 0.5 * (k + 1)  # half a second per evaluation
        bar(k + 1, 3.0)
    bar.statistics("profile", 1, 8)
    now[0] = 31.0
    bar.statistics("profile", 2, 8)
    bar.close()
    lines = stream.getvalue().splitlines()
    assert lines[0] == "fit: 20 of at most 100 evaluations, cost 3; 10 s so far, at most 40 s left"
    assert lines[1].startswith("fit: 40 of at most 100 evaluations") and "30 s left" in lines[1]
    assert lines[2] == "statistics: cost profile 1, evaluation 2/8;    2 in all; 31 s so far"
    assert len(lines) == 3 and "\r" not in stream.getvalue()


def test_segments_that_disagree_beyond_their_noise_widen_the_sigma():
    """One output parameter seen by four 1 s segments of 100 samples (unit noise each, so a
    segment's own sigma is 0.1) whose optima are 0, +-d: the Birge ratio in closed form; segments
    that agree leave the sigma as it is."""
    t = np.arange(400) * 0.01
    rec = SimpleNamespace(t_imu_s=t, segment_s=1.0)
    seg = (t // 1.0).astype(int)
    params = [SimpleNamespace(step=1e-3)]

    def problem(optima):
        x = np.asarray(optima)[seg]
        return SimpleNamespace(
            params=params, recs=[rec], weighted=lambda theta: [((theta[0] - x) / 1.0)[:, None]]
        )

    d = 0.3
    optima = [0.0, d, -d, 0.0]
    ratio = profile.segment_spread(problem(optima), np.zeros(1), np.array([True]), 0.005)
    expected = np.sqrt(np.sum(100.0 * np.square(optima)) / 3.0)  # a_i = 100, mean 0
    assert ratio[0] == pytest.approx(expected, rel=1e-6)
    close = problem([0.01, 0.0, -0.01, 0.0])
    agree = profile.segment_spread(close, np.zeros(1), np.array([True]), 0.005)
    assert agree[0] == 1.0
    held = profile.segment_spread(problem(optima), np.zeros(1), np.array([False]), 0.005)
    assert held[0] == 1.0


def test_a_residual_of_another_length_is_walled_and_named():
    """A parameter vector whose filter fuses a different number of values (its residual has
    another length) is a break: walled, so the solver backs off, and named."""
    problem = Problem(np.zeros(5))
    problem._length = None
    first = problem._walled(np.zeros(5), np.ones(4), "")
    short = problem._walled(np.zeros(5), np.ones(3), "")
    assert len(first) == len(short) == 4
    assert short[-1] == FAILED_RESIDUAL and short[0] == 1.0
    assert problem.failures == [
        "3 residuals where the first evaluation had 4 at J3 1, bar_mass 1, stiffness 1, "
        "damping 1, mounting.roll 0"
    ]


def test_held_loose_is_the_covariance_given_the_loose_ones():
    """The Schur complement: the inverse of the information of the others alone."""
    from gyrohost.ident.fit import held_loose

    root = RNG.normal(size=(3, 3))
    cov = root @ root.T + np.diag([0.1, 0.1, 40.0])
    loose = np.array([False, False, True])
    held = held_loose(cov, loose)
    keep = ~loose
    np.testing.assert_allclose(
        held[np.ix_(keep, keep)], np.linalg.inv(np.linalg.inv(cov)[np.ix_(keep, keep)]), rtol=1e-10
    )
    assert not held[loose].any() and not held[:, loose].any()
    assert held_loose(cov, np.zeros(3, bool)) is cov


def test_a_loose_parameter_does_not_break_the_others_profiles():
    """Two parameters correlated, the second barely seen (a node noise on a log that does not
    fix it: linearised sigma 3.3) and its model broken beyond 5 (the filter at a factor e^5):
    the first's profile along the full covariance steps the second by tens and breaks, so it
    had no sigma; with the second held it reads the first's own, and the second stays loose."""
    from gyrohost.ident.fit import secant_sigmas

    class Loose:
        dynamic = np.array([True, True])

        def __init__(self):
            self.failures = []

        def __call__(self, theta):
            if abs(theta[1]) > 5.0:
                self.failures.append("broke")
                return np.full(2, FAILED_RESIDUAL)
            return np.array([10.0 * theta[0] + 0.3 * theta[1], 0.3 * theta[1]])

        def batch(self, thetas):
            return [self(t) for t in thetas]

    J = np.array([[10.0, 0.3], [0.0, 0.3]])
    cov = np.linalg.inv(J.T @ J)  # sigmas 0.14 and 3.3, correlation -0.95
    sigma, _ = secant_sigmas(Loose(), np.zeros(2), cov, np.ones(2, bool), 1.0, 0.0)
    assert sigma[0] == pytest.approx(0.1, rel=1e-6)  # theta[1] held: the cost 50 theta[0]^2
    assert sigma[1] >= 1.0
