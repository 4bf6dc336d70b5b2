"""The pieces of the SIL that the consistency studies build on, checked exactly: the in-process
servos' paths through a goal sent within a step, the kink weight of the rest-length jitter and the
linearisation's residual (with the damper's jump), the kink noise's columns through a string near
its kink. The Monte
Carlo itself (NEES and NIS of 6-20 seeds against the bounds of their average, and the share of
time steps inside them) is a statistical claim and a study: ``python -m studies estimator_sil``
and ``python -m studies estimator_effects`` (reports/)."""

import numpy as np
import pytest


def test_in_process_servos_take_each_goal_from_its_send_within_a_step():
    """A goal sent 1.7 ms into a 5 ms step moves the servo from then on: the step's path, at
    its pieces' ends and the send, is the lag (at most at the speed limit) stepped in 1 us."""
    from gyrohost.config import ServoConfig
    from gyrohost.drivers.mx12 import lag_error_after
    from gyrohost.sil.scoring import SERVO_PIECES, servo_paths

    servo = ServoConfig(name="s", id=1, pulley_radius_m=0.01, max_speed_m_s=0.15, string="s13")
    lag, dt = 0.0133, 0.005
    later = [(0.0017, np.array([0.4040]))]
    ends, paths = servo_paths([(servo, 0)], {1: 0.4}, np.array([0.4015]), later, dt, lag)
    assert ends == sorted({*np.round(SERVO_PIECES * dt, 12), 0.0017}) and ends[-1] == dt
    x, fine = 0.4, []
    for k in range(1, 5001):
        goal = 0.4015 if k * 1e-6 <= 0.0017 + 1e-12 else 0.4040
        x = goal - float(lag_error_after(goal - x, 1e-6, lag, 0.15))
        fine.append(x)
    expected = [fine[int(round(e * 1e6)) - 1] for e in ends]
    assert np.allclose(paths[1], expected, rtol=0, atol=1e-12)
    assert np.ptp(np.diff(fine)) > 1e-9  # the send bent the path


def test_kink_weight_is_the_mean_square_of_the_rectified_jitter():
    from gyrohost.estimator.kink import kink_weight

    z = np.random.default_rng(0).standard_normal(400_000)
    for a in (-2.0, -0.7, 0.0, 0.5, 1.5, 4.0):
        sampled = np.mean((np.maximum(a - z, 0.0) - max(a, 0.0)) ** 2)
        assert abs(kink_weight(a) - sampled) < 0.01, a
    assert kink_weight(-8.0) < 1e-12 and abs(kink_weight(8.0) - 1.0) < 1e-12


def test_unexplained_variance_is_what_the_best_line_leaves_of_the_rectifier():
    from gyrohost.estimator.kink import unexplained_variance

    z = np.random.default_rng(0).standard_normal(400_000)
    for a in (-2.0, -0.7, 0.0, 0.5, 1.5, 4.0):
        f = np.maximum(a + z, 0.0)
        slope, intercept = np.polyfit(z, f, 1)
        assert abs(unexplained_variance(a) - np.mean((f - intercept - slope * z) ** 2)) < 0.005, a
    assert unexplained_variance(0.0) == pytest.approx(0.25 - 1.0 / (2.0 * np.pi), rel=1e-12)
    assert abs(unexplained_variance(-8.0)) < 1e-12 and abs(unexplained_variance(8.0)) < 1e-12


def test_unexplained_variance_with_a_jump_is_the_best_line_s_residual_by_quadrature():
    """A string that goes taut while it lengthens pulls at once with its damping: the force is
    ``(a + z + j) 1[a + z > 0]``. The best line's residual against a weighted least-squares fit
    over the midpoints of a fine grid of ``z`` whose cells' edges hold every ``-a`` (the jump
    falls between cells: midpoint rule, error far below the 1e-6 asked); at the kink it is
    ``(1/4 - 1/(2 pi)) (1 + j^2)``."""
    from gyrohost.estimator.kink import unexplained_variance

    h = 5e-5
    z = np.arange(-12.0 + h / 2, 12.0, h)
    w = np.exp(-0.5 * z * z) * h / np.sqrt(2.0 * np.pi)
    for a, j in ((0.0, 3.0), (1.0, 2.0), (-2.0, 5.0), (0.5, 0.1), (-0.7, 0.0)):
        f = (a + z + j) * (a + z > 0.0)
        mean_f, mean_z = w @ f, w @ z
        slope = (w @ ((f - mean_f) * (z - mean_z))) / (w @ (z - mean_z) ** 2)
        residual = w @ (f - mean_f - slope * (z - mean_z)) ** 2
        assert abs(unexplained_variance(a, j) - residual) < 1e-6, (a, j)
    kink = 0.25 - 1.0 / (2.0 * np.pi)
    assert unexplained_variance(0.0, 4.0) == pytest.approx(kink * 17.0, rel=1e-12)


def test_an_uncertain_margin_at_the_kink_adds_its_unexplained_variance_along_the_string(model):
    """With no jitter, the kink's noise is the linearisation's: the margin's variance ``g P
    g^T`` (``g`` here from central differences of the margins), times ``1/4 - 1/(2 pi)`` at the
    kink, through the same columns as the jitter."""
    from gyrohost.estimator import EstimatorConfig
    from gyrohost.estimator.layout import from_model_state, layout_of
    from gyrohost.estimator.process_model import ProcessModel

    dt = 0.01
    pm = ProcessModel(model, EstimatorConfig())
    L = layout_of(model)
    x = from_model_state(model, model.initial_state(), model.input_at(0.0))
    _, F = pm.step(x, model.input_at(0.0), dt)
    rng = np.random.default_rng(3)
    root = rng.standard_normal((L.size, L.size)) * 1e-3
    P = root @ root.T
    g = np.empty((L.n_strings, L.n_dynamic))
    for j in range(L.n_dynamic):
        X = np.tile(x[: L.n_dynamic], (2, 1))
        X[:, j] += (-1e-7, 1e-7)
        # at t = 0 the strings rest at their kink with no motion, where the two sides of the
        # min are equal: the tie takes the stretch
        stretch, _ = pm.margins(X)
        g[:, j] = (stretch[1] - stretch[0]) / 2e-7
    sigma2 = np.einsum("ij,jk,ik->i", g, P[: L.n_dynamic, : L.n_dynamic], g)
    margin = pm.tension_margins(x)[0]
    G = pm.taut_columns(dt, F, x, margin)
    n = L.q_dot.stop
    added = pm.noise(dt, F, x, P) - pm.noise(dt)
    assert np.all(np.abs(margin) < 1e-9)
    expected = (G * (0.25 - 1.0 / (2.0 * np.pi)) * sigma2) @ G.T
    assert np.abs(added[:n, :n] - expected).max() < 1e-6 * np.abs(expected).max()
    assert not added[n:].any() and not added[:, n:].any()
    # lengthening, each string's force jumps by its damping at the kink: (c/k) s_dot = J
    # adds (J / sigma)^2 times as much again
    x_moving = x.copy()
    x_moving[L.q_dot] = np.random.default_rng(2).normal(scale=0.05, size=3 * L.m)
    s, s_dot = pm.string_lengths(x_moving)
    damping = pm.dyn.c_s / pm.dyn.k_s * s_dot
    # at the kink again (min(stretch, damped) = 0), a hair taut: none goes taut in the step
    x_moving[L.rest] = s + np.minimum(damping, 0.0) - 1e-12
    jump = np.maximum(damping, 0.0)
    assert np.any(jump > 0.0) and np.any(jump == 0.0)
    _, F = pm.step(x_moving, model.input_at(0.0), dt)
    margin, g = pm.tension_margins(x_moving)
    assert np.all(np.abs(margin) < 1e-12)
    sigma2 = np.einsum("ij,jk,ik->i", g, P[: L.n_dynamic, : L.n_dynamic], g)
    G = pm.taut_columns(dt, F, x_moving, margin)
    added = pm.noise(dt, F, x_moving, P) - pm.noise(dt)
    var = (0.25 - 1.0 / (2.0 * np.pi)) * (sigma2 + jump**2)
    expected = (G * var) @ G.T
    assert np.abs(added[:n, :n] - expected).max() < 1e-6 * np.abs(expected).max()
    # slack by half a step's lengthening and exactly known: each lengthening string goes taut
    # mid-step, where the RK4 stages of its substep (of n) place its jump to within (J / n)^2
    # / 36 of the step; no other term
    x_moving[L.rest] = s + 0.5 * s_dot * dt
    _, F = pm.step(x_moving, model.input_at(0.0), dt)
    G = pm.taut_columns(dt, F, x_moving, pm.tension_margins(x_moving)[0])
    added = pm.noise(dt, F, x_moving, np.zeros_like(P)) - pm.noise(dt)
    expected = (G * (jump / pm.substeps(dt)) ** 2 / 36.0) @ G.T
    assert np.abs(added[:n, :n] - expected).max() < 1e-12 * np.abs(expected).max()


def test_a_split_step_gets_the_whole_step_s_linearisation_noise(model):
    """The linearisation's error is a filter step's (``process_dt_s``): a step cut in two by
    another sample's time gets about half of it in each half, as white noise would (the
    response ``G`` halves with the step, its square quarters: without the share a half got 0.3
    of the whole, the halves' sum well under it). The strings' stiff response within the step
    (``F`` against the identity) moves the half's share off 0.5 (0.6 here)."""
    from gyrohost.estimator import EstimatorConfig
    from gyrohost.estimator.layout import from_model_state, layout_of
    from gyrohost.estimator.process_model import ProcessModel

    pm = ProcessModel(model, EstimatorConfig())
    L = layout_of(model)
    x = from_model_state(model, model.initial_state(), model.input_at(0.0))
    root = np.random.default_rng(3).standard_normal((L.size, L.size)) * 1e-3
    P = root @ root.T
    velocities = []
    for dt in (0.01, 0.005):
        _, F = pm.step(x, model.input_at(0.0), dt)
        added = pm.noise(dt, F, x, P) - pm.noise(dt)
        velocities.append(np.trace(added[L.q_dot, L.q_dot]))
    assert 0.4 < velocities[1] / velocities[0] < 0.8, velocities


def test_the_margins_and_their_gradient_in_closed_form_are_the_complex_steps(model):
    """On a moving state with one string on each side of its ``min`` (the damped stretch the
    smaller where the string shortens)."""
    from dataclasses import replace

    from gyrohost.estimator import EstimatorConfig
    from gyrohost.estimator.layout import from_model_state, layout_of
    from gyrohost.estimator.process_model import ProcessModel

    L = layout_of(model)
    x = from_model_state(model, model.initial_state(), model.input_at(0.0))
    x[L.q_dot] = np.random.default_rng(2).normal(scale=0.05, size=3 * L.m)
    closed = ProcessModel(model, EstimatorConfig())
    stepped = ProcessModel(model, replace(EstimatorConfig(), jacobian="complex-step"))
    _, s_dot = closed.string_lengths(x)
    assert np.any(s_dot < 0.0) and np.any(s_dot > 0.0)
    margin, g = closed.tension_margins(x)
    margin_cs, g_cs = stepped.tension_margins(x)
    assert np.abs(g - g_cs).max() < 1e-12 * np.abs(g).max()
    np.testing.assert_allclose(margin, margin_cs, rtol=0.0, atol=1e-15)
    stretch, damped = closed.margins(x[None, : L.n_dynamic])
    np.testing.assert_allclose(margin, np.minimum(stretch, damped)[0], atol=1e-15)


def test_rest_jitter_reaches_the_nodes_through_slack_strings_near_their_kink(model):
    from dataclasses import replace

    from gyrohost.estimator import EstimatorConfig
    from gyrohost.estimator.kink import kink_weight
    from gyrohost.estimator.layout import from_model_state, layout_of
    from gyrohost.estimator.process_model import ProcessModel

    q, dt = 2e-10, 0.01
    pm = ProcessModel(model, replace(EstimatorConfig(), rest_jitter_psd_m2_s=q))
    L = layout_of(model)
    x = from_model_state(model, model.initial_state(), model.input_at(0.0))
    x_next, F = pm.step(x, model.input_at(0.0), dt)
    assert np.array_equal(pm.noise(dt), pm.noise(dt, F))  # no state: no jitter term
    margin = pm.tension_margins(x)[0]
    G = pm.taut_columns(dt, F, x, margin)
    # each column: the trapezoid rule dt/2 (b + F b) for b = (0, d acceleration / d rest_i) of
    # the string held taut, here from central differences of the model's accelerations
    s, _ = pm.string_lengths(x)
    n = L.q_dot.stop
    for i in range(L.n_strings):
        X = np.tile(x[: L.n_dynamic], (2, 1))
        X[:, L.rest] = s - 2e-3  # both strings taut
        X[:, L.rest.start + i] += (-1e-7, 1e-7)
        acc = pm.derivative(X, model.input_at(0.0))[:, L.q_dot]
        b = np.zeros(n)
        b[L.q_dot] = (acc[1] - acc[0]) / 2e-7
        expected = 0.5 * dt * (b + F[:n, L.q_dot] @ b[L.q_dot])
        assert np.linalg.norm(G[:, i] - expected) < 1e-6 * np.linalg.norm(expected)
    P0 = np.zeros((L.size, L.size))  # an exact estimate: no linearisation error
    added = pm.noise(dt, F, x, P0) - pm.noise(dt)
    w = kink_weight(margin / np.sqrt(q / dt))
    assert np.allclose(added[:n, :n], q / dt * (G * w) @ G.T)
    assert not added[n:].any() and not added[:, n:].any()
    # at t = 0 both strings sit exactly at their rest length (the kink, slack for the model):
    # half the taut noise, where the taut-only mapping added nothing
    assert np.all(np.abs(margin) < 1e-9) and np.allclose(w, 0.5)
    assert np.abs(added).max() > 0.0
    # deep slack: nothing added; at the kink half the taut noise
    x_slack = x.copy()
    x_slack[L.rest] += 0.01
    _, F_slack = pm.step(x_slack, model.input_at(0.0), dt)
    assert np.abs(pm.noise(dt, F_slack, x_slack, P0) - pm.noise(dt)).max() < 1e-30
