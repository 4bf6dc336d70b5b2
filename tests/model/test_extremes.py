"""Stability at the extremes: behaviour pinned at the corners of the sweep of `gyrotens bench`.

A corner either holds (constraints and conserved quantities checked) or fails with a clear
SimulationError naming time and member; never NaN in the output, never a hang.
"""

import warnings

import numpy as np
import pytest
from scipy.integrate import DOP853

from gyrohost.bench.extremes import (
    ACCURACY_CLASS,
    extent,
    near_flat_dbar,
    prism,
    reference,
    run_cell,
    with_spin,
    zero_length_crossing,
)
from gyrotensegrity import Model, SimulationError, Stepper, scene_from_dict, simulate
from gyrotensegrity.fast import FastDynamics
from gyrotensegrity.simulate import explicit_steps


def model_of(data):
    return Model(scene_from_dict(data, source="corner"))


def drift(series):
    series = np.asarray(series)
    scale = np.max(np.linalg.norm(np.atleast_2d(series.T).T.reshape(len(series), -1), axis=1))
    return np.max(np.abs(series - series[0])) / scale


def test_stiff_string_refused_for_rk4_with_the_implicit_hint():
    model = model_of(prism(stiffness=1e7))
    with pytest.raises(SimulationError, match=r"stiff: s\d .*radau or bdf") as exc:
        simulate(model, duration=0.1, integrator="rk4", dt=1e-3, fast=True)
    assert exc.value.t_s == 0.0 and exc.value.member.startswith("s")
    with pytest.raises(SimulationError, match="stiff"):
        Stepper(model, max_dt=1e-3)


def test_explicit_adaptive_refused_when_it_would_take_millions_of_steps():
    model = model_of(prism(stiffness=1e13))
    with pytest.raises(SimulationError, match=r"dop853 needs about .* steps; use an implicit"):
        simulate(model, duration=10.0, integrator="dop853", fast=True)


def tiny_masses():
    """The prism with bars and wheels of 1e-9 kg: the strings' oscillation is the motion."""
    data = prism()
    for bar in data["bars"]:
        bar["mass"] = bar["wheel"]["mass"] = 1e-9
    return model_of(data)


def test_step_estimate_for_tiny_masses_matches_the_steps_taken():
    """The stability bound alone (3 rad of the string's oscillation per step) estimated 44
    steps here; resolving the motion to rtol takes about 800."""
    model = tiny_masses()
    fd, x0, u0 = FastDynamics(model), model.initial_state(), model.input_at(0.0)
    solver = DOP853(lambda t, x: fd.rhs(t, x, u0), 0.0, x0, 5e-4, rtol=1e-8, atol=1e-14)
    steps = 0
    while solver.status == "running":
        solver.step()
        steps += 1
    estimate, why, member = explicit_steps(model, "dop853", 5e-4, 1e-8, x0, u0)
    assert 0.5 < estimate / steps < 2.0
    assert member in model.structure.node_names and f"node {member} accelerates" in why


def test_tiny_masses_refused_naming_the_node():
    model = tiny_masses()
    with pytest.raises(SimulationError, match=r"node \w+ accelerates .* needs about") as exc:
        simulate(model, duration=1.0, integrator="dop853", rtol=1e-12, fast=True)
    assert exc.value.t_s == 0.0 and exc.value.member in model.structure.node_names


@pytest.mark.parametrize("integrator", ["radau", "dop853"])
def test_stiff_string_holds_with_adaptive_integrators(integrator):
    model = model_of(prism(stiffness=1e7))
    run = simulate(model, duration=0.05, integrator=integrator, rtol=1e-7, atol=1e-10, fast=True)
    assert np.all(np.isfinite(run["N"]))
    assert np.max(np.abs(run["bar_length_error"])) < 1e-8
    assert drift(run["angular_momentum"]) < 1e-6


@pytest.mark.parametrize("integrator,opts", [("rk4", {"dt": 1e-4}), ("dop853", {"rtol": 1e-9})])
def test_wheels_at_3000_rad_s_hold(integrator, opts):
    run = simulate(
        model_of(with_spin(3000.0)),
        duration=0.1,
        integrator=integrator,
        atol=1e-12,
        fast=True,
        **opts,
    )
    assert np.max(np.abs(run["bar_length_error"])) < 1e-9
    assert np.max(run["joint_error"]) < 1e-12
    assert drift(run["angular_momentum"]) < 1e-7


def test_fold_instability_is_sensitive_not_holds():
    """Wheels at 1e4 rad/s: the D-bar's fold instability grows from round-off about
    e-fold per 20 ms, so DOP853 at rtol 1e-11 and 1e-13 part by about 1e-6 of the extent at
    0.8 s and 1e-2 at 1.0 s. The test runs to 1.0 s and asks the spread to be 100 x the
    DOP853 class: a CPU whose rounding seeds the growth 100 x smaller still passes, while a
    stable motion stays near the tolerances (about 1e-11). Each run alone keeps its
    constraints, which made the cell "hold" before."""
    data = with_spin(1e4)
    ref = reference(data, 1.0, budget_s=120.0)
    assert ref["spread"] > 100 * ACCURACY_CLASS["dop853"]
    cell = run_cell(data, 1.0, "dop853", 120.0, ref)
    assert cell["status"] == "sensitive" and "amplifies round-off" in cell["message"]
    assert cell["bar_length_error"] < 1e-9


def test_cell_holds_only_within_its_accuracy_class():
    data = with_spin(0.0)
    ref = reference(data, 0.1, budget_s=60.0)
    assert ref["spread"] < 1e-12
    cell = run_cell(data, 0.1, "rk4", 60.0, ref)
    assert cell["status"] == "holds" and cell["node_error"] < 1e-3
    size = extent(model_of(data))
    shifted = dict(ref, N=ref["N"] + 2e-3 * size)  # a reference 2e-3 x extent away
    assert run_cell(data, 0.1, "rk4", 60.0, shifted)["status"] == "inaccurate"
    assert run_cell(data, 0.1, "rk4", 60.0, dict(shifted, spread=1.0))["status"] == "sensitive"
    unfinished = {"message": "reference dop853 at rtol 1e-13 did not finish: budget"}
    cell = run_cell(data, 0.1, "rk4", 60.0, unfinished)
    assert cell["status"] == "unverified" and cell["message"] == unfinished["message"]


@pytest.mark.parametrize("ratio", [1e-4, 1e4])
def test_mass_ratio_corners_hold(ratio):
    model = model_of(prism(mass_ratio=ratio))
    run = simulate(model, duration=0.2, integrator="dop853", rtol=1e-10, atol=1e-13, fast=True)
    assert drift(run["angular_momentum"]) < 1e-9
    assert drift(run["energy"]) < 1e-8


def test_bar_length_1_mm_and_100_m_scale_exactly():
    """Scaling every length (wheels too) by s leaves the motion in time unchanged: N / s
    must agree with the 0.3 m prism (similarity, an independent check of the units)."""
    runs = {}
    for scale in (1.0, 1e-3 / 0.3, 100.0 / 0.3):
        model = model_of(prism(scale=scale))
        run = simulate(
            model,
            duration=0.3,
            integrator="dop853",
            rtol=1e-11,
            atol=1e-14 * scale,
            constraint_tolerance=1e-3 * scale,
            fast=True,
        )
        runs[scale] = run["N"] / scale
    ref = runs.pop(1.0)
    for N in runs.values():
        assert np.max(np.abs(N - ref)) < 1e-8


def test_collinear_loop_fails_clearly_on_both_paths():
    """The D-bar folded flat: its closed loop of bar constraints is singular. The fast path
    names the bar; the reference path (sparse solve) names the node whose rate is not finite
    instead of letting scipy's step-size loop spin on NaN (it would never return)."""
    model = model_of(near_flat_dbar(0.0))
    with pytest.raises(SimulationError, match=r"singular at b\d\d") as exc:
        simulate(model, duration=0.1, fast=True)
    assert exc.value.t_s == 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy's singular-matrix and overflow warnings
        with pytest.raises(SimulationError, match=r"n1: rate not finite"):
            simulate(model, duration=0.1, integrator="dop853")
        with pytest.raises(SimulationError, match=r"n1 position is not finite"):
            simulate(model, duration=0.1, integrator="rk4", dt=1e-3)


def test_nearly_collinear_bars_hold():
    model = model_of(near_flat_dbar(1e-4))
    run = simulate(model, duration=0.1, fast=True)
    assert np.all(np.isfinite(run["N"]))
    assert np.max(np.abs(run["bar_length_error"])) < 1e-10


@pytest.mark.parametrize("integrator", ["rk4", "dop853"])
def test_string_through_zero_length_stays_finite(integrator):
    model = model_of(zero_length_crossing())
    run = simulate(model, duration=1.0, integrator=integrator, dt=1e-3, fast=integrator == "rk4")
    a = model.structure.primary["a"]
    assert run["N"][0, 0, a] < 0.0 < run["N"][-1, 0, a]  # it went through the anchor
    assert np.all(np.isfinite(run["N"])) and np.all(np.isfinite(run["energy"]))
    assert drift(run["energy"]) < 1e-6


def test_nearly_slack_strings_hold():
    run = simulate(
        model_of(prism(prestress=1.0 - 1e-6)), duration=0.3, rtol=1e-10, atol=1e-13, fast=True
    )
    assert drift(run["energy"]) < 1e-9


def test_non_finite_state_names_time_and_member():
    model = model_of(prism())

    def broken(t, x, u, params):
        return u * (np.nan if t >= 0.05 else 1.0)

    with pytest.raises(SimulationError, match=r"t = 0\.0[56]\d* s: .*not finite") as exc:
        simulate(model, duration=0.2, integrator="rk4", dt=1e-3, control=broken, fast=True)
    assert exc.value.member in model.structure.node_names
    assert np.all(np.isfinite(exc.value.partial["N"]))


@pytest.mark.slow
def test_long_horizon_prism_keeps_energy_and_momentum():
    """60 s of the free prism (the bench runs 1,000 s)."""
    model = model_of(prism())
    run = simulate(model, duration=60.0, sample_dt=0.5, rtol=1e-11, atol=1e-14, fast=True)
    assert drift(run["energy"]) < 1e-7
    assert drift(run["angular_momentum"]) < 1e-9
