"""The planner's reduced model against closed forms of the rhombus (Eqs. 12 and 16)."""

import numpy as np
import pytest

from gyrohost.control import DBarReduced, PlanError
from gyrohost.resources import shipped


def test_tables_match_closed_forms(dbar):
    r = DBarReduced(dbar)
    d = np.linspace(0.15, 0.55, 9)
    bar_l, m_t, J_t, J3 = dbar.l[0], dbar.m_t[0], dbar.J_t[0], dbar.J3[0]
    # rotation about y: bar centres at x = +-d/4, bar vectors with x-component +-d/2
    np.testing.assert_allclose(r.inertia(d), 4.0 * (m_t * d**2 / 16 + J_t * d**2 / 4), rtol=1e-4)
    h = 0.5 * np.sqrt(4 * bar_l**2 - d**2)  # half the n2-n4 distance
    spin = abs(dbar.spin0[0])
    np.testing.assert_allclose(
        r.wheel_momentum(d, dbar.spin0), 4 * J3 * spin * h / bar_l, rtol=1e-4
    )


def test_momentum_at_rest_is_the_wheels(dbar):
    r = DBarReduced(dbar)
    H = r.momentum(dbar.initial_state(), dbar.input_at(0.0))
    assert H == pytest.approx(
        float(r.wheel_momentum(r.d_rest, dbar.spin0)), rel=1e-5
    )  # table interpolation
    assert r.tilt_rates(np.array([r.d_rest]), H, dbar.spin0)[0] == pytest.approx(0.0, abs=1e-5)


def test_other_structures_are_refused():
    from gyrotensegrity import Model, load_scene

    with pytest.raises(PlanError, match="four bars|no node"):
        DBarReduced(Model(load_scene(shipped("scene", "prism-gyro"))))
