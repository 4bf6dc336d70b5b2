"""The observed NEES split into its blocks (positions, wheels, rest lengths), as
``gyrotens sil --realtime`` prints them, and the shares of steps each block spends below,
inside and above its bounds."""

import numpy as np
import pytest

from gyrohost.estimator import TensegrityEKF
from gyrohost.estimator.consistency import (
    average_bounds,
    observed_blocks,
    observed_nees,
    translation,
)
from gyrohost.resources import shipped
from gyrohost.sil.montecarlo import ScoredRun, summarise
from gyrotensegrity import Model, load_scene


@pytest.fixture()
def ekf(model, config):
    return TensegrityEKF(model, config)


def test_blocks_add_up_to_the_observed_nees_where_the_covariance_does_not_couple_them(ekf):
    L = ekf.layout
    assert not ekf.P[L.q, L.omega.start : L.rest.stop].any()  # the initial covariance
    x_true = ekf.x + 1e-3 * np.random.default_rng(3).standard_normal(len(ekf.x))
    blocks = observed_blocks(ekf, x_true)
    total, dof = observed_nees(ekf, ekf.x, ekf.P, x_true)
    # the positions: 12 coordinates, less 4 bar lengths, less the 3 of the D-bar's translation
    assert {name: d for name, (_, d) in blocks.items()} == {"positions": 5, "wheels": 4, "rest": 2}
    assert sum(d for _, d in blocks.values()) == dof
    assert sum(v for v, _ in blocks.values()) == pytest.approx(total, rel=1e-9)


def test_a_two_sigma_error_of_one_wheel_scores_four_in_the_wheels_alone(ekf):
    L = ekf.layout
    x_true = ekf.x.copy()
    w = L.omega.start + 2
    x_true[w] += 2.0 * np.sqrt(ekf.P[w, w])
    blocks = observed_blocks(ekf, x_true)
    assert blocks["wheels"][0] == pytest.approx(4.0, rel=1e-9)
    assert blocks["positions"][0] == 0.0 and blocks["rest"][0] == 0.0


def test_an_error_that_stretches_a_bar_is_not_a_position_error(ekf, model):
    """The positions are scored in the tangent space of the bar lengths: the filter's state
    never leaves it, so an error across it is the truth's, not the estimate's."""
    L = ekf.layout
    across = ekf.manifold.jacobian(ekf.x)[0, L.q]  # the first bar's length gradient
    along = np.linalg.svd(ekf.manifold.jacobian(ekf.x)[: model.beta, L.q])[2][-1]
    x_true = ekf.x.copy()
    x_true[L.q] += 1e-3 * across / np.linalg.norm(across)
    assert observed_blocks(ekf, x_true)["positions"][0] < 1e-20
    x_true = ekf.x.copy()
    x_true[L.q] += 1e-3 * along
    assert observed_blocks(ekf, x_true)["positions"][0] > 1e-3


def test_the_translation_of_a_free_structure_is_not_scored(ekf, model):
    """No sensor and no force the model does not know moves the whole structure: an error
    along its translation is the start's, not the filter's (consistency.scored_positions)."""
    L = ekf.layout
    shift = translation(model)
    N = model.U2.toarray() @ shift[: L.m, 0]  # every node's x, moved by the first column
    assert N == pytest.approx(np.full(len(N), N[0]), abs=1e-12) and N[0] != 0.0
    x_true = ekf.x.copy()
    x_true[L.q] += 1e-3 * shift @ np.array([1.0, -2.0, 0.5])
    assert observed_blocks(ekf, x_true)["positions"][0] < 1e-20


def test_a_structure_held_at_a_node_has_no_translation():
    assert translation(Model(load_scene(shipped("scene", "double-pendulum")))) is None


def test_each_block_reports_the_steps_it_spends_below_inside_and_above_its_bounds(capsys):
    runs, steps = 4, 10
    lo, hi = average_bounds(2, runs)
    # five steps far under the bounds, three at the dof, two far over, in every run
    rest = np.r_[np.zeros(5), np.full(3, 2.0), np.full(2, 10.0 * hi)]
    run = ScoredRun(
        t_s=np.linspace(0.0, 0.9, steps),
        nees=np.full(steps, 14.0),
        nees_dof=14,
        tilt_rad=np.zeros(steps),
        position_m=np.zeros(steps),
        nis={},
        cpu_s=0.0,
        blocks={"rest": (rest, 2)},
    )
    figures = summarise([run] * runs, "[t] ")
    shares = figures["blocks"]["rest"]
    assert (shares["below"], shares["inside"], shares["above"]) == pytest.approx((0.5, 0.3, 0.2))
    assert "steps 50 % below, 30 % inside, 20 % above" in capsys.readouterr().out
