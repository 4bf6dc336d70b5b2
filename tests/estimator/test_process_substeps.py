"""The lean model's RK4 substeps and its ``F`` through their stages.

The substeps are the fewest that keep ``omega h`` within ``RK4_ACCURATE`` for the scene's
fastest oscillation; ``F`` chained through the stages is the Jacobian of the RK4 map itself,
checked against that map differentiated by the complex step (the derivative is complex-step
safe), to round-off: ``|A h|`` reaches ~1 on the D-bar, so entries sum terms of order 1 and
1e-10 leaves five orders for another CPU's BLAS while a wrong stage moves ``F`` by 1e-3 or
more."""

import numpy as np

from gyrohost.estimator import complex_step
from gyrohost.estimator.process_model import RK4_ACCURATE, RK4_STEP_ERROR, ProcessModel
from gyrotensegrity.diagnostics import highest_frequency

DT_S = 0.01
RTOL = 1e-10


def test_the_accurate_substep_is_rk4_s_error_share():
    """``(omega h)^5 / 120`` at ``RK4_ACCURATE`` is the error share asked for."""
    assert np.isclose(RK4_ACCURATE**5 / 120.0, RK4_STEP_ERROR, rtol=1e-12)


def test_the_lean_model_takes_the_fewest_accurate_substeps(model, config):
    """On the D-bar (strings at up to 120 rad/s) 10 ms is one step too coarse: two substeps."""
    pm = ProcessModel(model, config)
    omega, _ = highest_frequency(model)
    n = pm.substeps(DT_S)
    assert omega * DT_S / n <= RK4_ACCURATE < omega * DT_S / (n - 1)
    assert n == 2


def _exact_jacobian(pm, x, u, dt, sp0):
    X = complex_step.perturbed(x, pm.columns)
    return complex_step.split(pm._rk4_substeps(X, u, dt, sp0))


def test_f_chained_through_the_stages_is_the_rk4_map_s_jacobian(model, config, moving_state):
    """Without the carried ``A`` (every substep's own at its start) the chain is exact; the
    lean model's first substep alone (one substep's step) is too."""
    pm = ProcessModel(model, config)
    x0, _, u = moving_state
    x = x0[: pm.layout.n_dynamic]
    u = np.concatenate([x[pm.layout.rest], u[model.alpha :]])
    x_chain, F_chain = pm._rk4_closed_form(x, u, DT_S, None)
    x_exact, F_exact = _exact_jacobian(pm, x, u, DT_S, None)
    assert np.max(np.abs(x_chain - x_exact)) <= RTOL * np.max(np.abs(x_exact))
    assert np.max(np.abs(F_chain - F_exact)) <= RTOL * np.max(np.abs(F_exact))
    pm.lean_substep_s = np.inf
    _, F_lean = pm.step(x, u, DT_S)
    _, F_one = _exact_jacobian(pm, x, u, DT_S, None)
    assert np.max(np.abs(F_lean - F_one)) <= RTOL * np.max(np.abs(F_one))
