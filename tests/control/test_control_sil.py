"""SIL: truth with 20 % more wheel spin inertia; closed loop must land nearer the target.

Truth = the shipped dbar-gyro scene with every wheel's J_3 x 1.2; planner = the nominal scene;
target tilt -0.3 rad, landing at 4 s, servos at 0.05 m/s, re-planning at 4 Hz from the truth
state plus noise (1 mm, 2 mm/s).
"""

import numpy as np
import pytest

from gyrohost.control import DBarReduced, Replanner
from gyrohost.control.adapt import WheelGainFit
from gyrohost.control.sil import run_sil, scene_with_wheel_inertia
from gyrohost.resources import shipped
from gyrotensegrity import Model

# Half a minute of simulated maneuvers on one core: beside the simulated rig's real-time tests
# (tests/conftest.py), whose second core would otherwise idle.
pytestmark = pytest.mark.slow

SCENE = shipped("scene", "dbar-gyro")
TARGET, DURATION = -0.3, 4.0


@pytest.fixture(scope="module")
def truth():
    return Model(scene_with_wheel_inertia(SCENE, 1.2))


def test_truth_has_the_scaled_inertia(dbar, truth):
    np.testing.assert_allclose(truth.J3, 1.2 * dbar.J3, rtol=1e-12)
    np.testing.assert_allclose(truth.m_t, dbar.m_t)


def test_plan_matches_the_full_model(dbar, planner):
    """The reduced model's prediction against the full model run on the same schedule."""
    r = run_sil(dbar, planner, TARGET, DURATION, closed_loop=False)
    predicted = r.plans[0].predicted_tilt_rad
    assert r.final_tilt_rad == pytest.approx(predicted, abs=2e-3)
    assert abs(r.final_rate_rad_s) < 1e-3  # landed: the plane stopped turning


def test_closed_loop_lands_nearer_than_open_loop(truth, planner):
    open_ = run_sil(truth, planner, TARGET, DURATION, closed_loop=False)
    closed = run_sil(truth, planner, TARGET, DURATION, closed_loop=True, seed=3, adapt=False)
    print(f"open loop error {open_.error_rad:+.4f} rad, closed loop {closed.error_rad:+.4f} rad")
    assert abs(open_.error_rad) > 0.03  # the 20 % inertia error shows in open loop
    assert abs(closed.error_rad) < 0.25 * abs(open_.error_rad)
    assert all(p.accepted for p in closed.plans)
    assert len(closed.plans) == 16  # 4 Hz over 4 s
    for r in (open_, closed):  # both land: back at the rest shape, the plane stops turning
        np.testing.assert_allclose(r.schedule(DURATION), r.schedule(0.0), atol=1e-12)
        assert abs(r.final_rate_rad_s) < 1e-3


def test_gain_fit_learns_the_wheel_inertia(truth, planner):
    r = run_sil(truth, planner, TARGET, DURATION, closed_loop=True, seed=4, adapt=True)
    print(f"closed loop with gain fit: error {r.error_rad:+.4f} rad, gain {r.plans[-1].kappa:.3f}")
    assert r.plans[-1].kappa == pytest.approx(1.2, abs=0.04)
    assert abs(r.error_rad) < 0.006  # open loop: 0.06


def test_gain_fit_on_exact_samples(dbar):
    """Samples made with the reduced model's own law at a known gain and momentum."""
    red = DBarReduced(dbar)
    omega = dbar.spin0
    kappa, H = 1.3, 1.3 * float(red.wheel_momentum(red.d_rest, omega))
    fit = WheelGainFit(red, momentum0=H / 1.3, omega_w=omega, rate_std_rad_s=1e-3)
    for d in np.linspace(red.d_rest, 0.3, 50):
        fit.add(d, float(red.tilt_rates(np.array([d]), H, kappa * omega)[0]))
    H_fit, kappa_fit, std = fit.estimate()
    assert kappa_fit == pytest.approx(kappa, abs=1e-3)
    assert H_fit == pytest.approx(H, rel=1e-3)
    assert std < 0.01


def test_replanner_period_and_continuity(dbar, planner):
    loop = Replanner(planner, TARGET, 0.0, DURATION, period_s=0.5, adapt=False)
    x = dbar.initial_state()
    first = loop.update(0.0, x)
    for k in range(1, 80):
        loop.update(0.01 * k, x)  # a state that does not turn: behind the plan at 0.5 s
    assert [round(r.t_s, 2) for r in loop.records] == [0.0, 0.5]
    np.testing.assert_allclose(loop.schedule(0.5), first(0.5), atol=1e-4)
    t = np.linspace(0.5, DURATION, 200)
    squeeze = [np.mean([s(ti)[0] for ti in t]) for s in (first, loop.schedule)]
    assert squeeze[1] < squeeze[0]  # the re-plan squeezes harder to catch up
    assert loop.records[1].predicted_tilt_rad == pytest.approx(TARGET, abs=1e-3)


def test_ekf_adapter_maps_the_filter_state(dbar):
    from types import SimpleNamespace

    from gyrohost.control.closed_loop import ekf_estimate

    x = dbar.initial_state()
    L = dbar.layout
    xf = np.concatenate([x[: L.q_dot.stop], dbar.spin0, [0.01, 0.02, 0.03]])  # + gyro bias
    t, back = ekf_estimate(SimpleNamespace(model=dbar, x=xf, t=1.5))()
    assert t == 1.5
    np.testing.assert_array_equal(back, x)
