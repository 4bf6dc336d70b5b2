"""A string going taut pulls at once with its damping (a jump in its force): the Stepper ends its
RK4 substep there (gyrotensegrity.engagement). Against an independent reference, scipy's DOP853
at rtol 1e-12 stopped by an event at the string's crossing and restarted from it."""

from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import gyrotensegrity
from gyrotensegrity import Model, Stepper, load_scene
from gyrotensegrity.engagement import Tautening
from gyrotensegrity.integrators import fixed_step
from gyrotensegrity.projection import project_velocities
from gyrotensegrity.simulate import dynamics_of

H = 0.005  # the simulated rig's truth step, s


@pytest.fixture(scope="module")
def going_taut():
    """The D-bar moving, its lengthening string slack by 40 % of a step's lengthening (taut 40 %
    into the step), the other shortening and slack; the input held."""
    model = Model(load_scene(Path(gyrotensegrity.__file__).parent / "scenes" / "dbar-gyro.toml"))
    x = model.initial_state()
    x[model.layout.q_dot] = np.random.default_rng(1).normal(scale=0.1, size=3 * model.m)
    x = project_velocities(model, x)
    u = model.input_at(0.0)
    s = Tautening(model).stretches(x, np.zeros_like(u))
    N, N_dot = model.nodes(x)
    st = model.structure
    S = N[:, st.string_end] - N[:, st.string_start]
    s_dot = np.einsum("ij,ij->j", S, N_dot[:, st.string_end] - N_dot[:, st.string_start]) / s
    assert s_dot[0] > 0.0 > s_dot[1]
    u[: model.alpha] = s + 0.4 * np.abs(s_dot) * H
    return model, x, u


def reference(model, x, u):
    """DOP853 over the step, stopped where string 0 goes taut and restarted there."""
    f, _ = dynamics_of(model, fast=True)

    tautening = Tautening(model)

    def taut(t, y):
        return tautening.stretches(y, u)[0]

    taut.terminal, taut.direction = True, 1.0
    first = solve_ivp(lambda t, y: f(t, y, u), (0.0, H), x, "DOP853", rtol=1e-12, atol=1e-14,
                      events=taut)  # fmt: skip
    assert first.status == 1 and 0.3 * H < first.t[-1] < 0.5 * H
    rest = solve_ivp(lambda t, y: f(t, y, u), (first.t[-1], H), first.y[:, -1], "DOP853",
                     rtol=1e-12, atol=1e-14)  # fmt: skip
    return rest.y[:, -1]


def test_the_stepper_ends_its_substep_where_a_string_goes_taut(going_taut):
    """One RK4 step across the jump misplaces its impulse by ``theta - 1/6`` of the step, a
    quarter of it here (``theta`` = 0.4): a sizeable share of the step's velocity change, of
    which 1 % is asked. Split there, what remains is RK4's ``h^5`` on two smooth parts and the
    crossing's place to 1e-9 of the step, orders below the misplaced impulse: a thousandth of
    the plain step's error is asked."""
    model, x, u = going_taut
    f, _ = dynamics_of(model, fast=True)
    exact = reference(model, x, u)
    plain = fixed_step("rk4", model, lambda t, y: f(t, y, u), 0.0, x, H)
    split = Stepper(model, x0=x, max_dt=H, fast=True).step(H, u)
    v = model.layout.q_dot
    plain_error = np.abs(plain[v] - exact[v]).max()
    assert plain_error > 1e-2 * np.abs(exact[v] - x[v]).max()  # the jump matters
    assert np.abs(split[v] - exact[v]).max() < 1e-3 * plain_error


def test_the_crossing_is_found_on_its_taut_side(going_taut):
    model, x, u = going_taut
    f, _ = dynamics_of(model, fast=True)

    def at(share):
        return fixed_step("rk4", model, lambda t, y: f(t, y, u), 0.0, x, share * H), u

    tautening = Tautening(model)
    N, _ = model.nodes(x)
    st = model.structure
    lengths = np.linalg.norm(N[:, st.string_end] - N[:, st.string_start], axis=0)
    np.testing.assert_allclose(tautening.stretches(x, u), lengths - u[: model.alpha], atol=1e-15)
    assert tautening.between((x, u), at(1.0))
    share = tautening.share((x, u), at)
    assert 0.3 < share < 0.5
    assert 0.0 < tautening.stretches(*at(share))[0] < 1e-12
    assert not tautening.between(at(share), at(1.0))
