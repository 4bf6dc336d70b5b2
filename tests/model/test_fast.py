"""The fast path (gyrotensegrity.fast) against the reference right-hand side, to round-off."""

from pathlib import Path

import numpy as np
import pytest

import gyrotensegrity
from gyrotensegrity import Model, SimulationError, evaluate, load_scene, rhs
from gyrotensegrity.fast import FastDynamics, fast_rhs
from gyrotensegrity.generators import prism_chain
from gyrotensegrity.projection import project_velocities

SCENES = sorted(  # the paper's model: the fast path refuses the rig-fidelity option
    p for p in (Path(gyrotensegrity.__file__).parent / "scenes").glob("*.toml")
    if load_scene(p).rig is None
)  # fmt: skip
TOL = 1e-12  # relative to the largest derivative


def random_states(model, count=4, seed=0):
    """States near the initial one: perturbed positions, random velocities and spins."""
    rng = np.random.default_rng(seed)
    L = model.layout
    for _ in range(count):
        x = model.initial_state()
        x[L.q] += rng.normal(scale=0.02, size=3 * model.m)
        x[L.q_dot] = rng.normal(scale=0.5, size=3 * model.m)
        x[L.omega] = rng.normal(scale=100.0, size=L.n_torque)
        yield project_velocities(model, x)


def random_input(model, rng):
    u = model.input_at(rng.uniform(0.0, model.scene.duration))
    u[: model.alpha] *= rng.uniform(0.9, 1.1, model.alpha)
    u[model.alpha :] = rng.normal(scale=50.0, size=u.size - model.alpha)
    return u


def assert_close(a, b):
    assert np.abs(a - b).max() <= TOL * np.abs(a).max()


@pytest.fixture(scope="module", params=[p.stem for p in SCENES])
def model(request):
    return Model(load_scene(SCENES[[p.stem for p in SCENES].index(request.param)]))


@pytest.mark.parametrize("kernel", [True, False], ids=["kernel", "numpy"])
def test_fast_matches_reference_on_every_scene(model, kernel):
    fast = FastDynamics(model, kernel=kernel)
    if not kernel:
        assert fast.kernel is None
    rng = np.random.default_rng(3)
    for x in random_states(model):
        u = random_input(model, rng)
        assert_close(rhs(0.3, x, u, model), fast_rhs(0.3, x, u, fast))


def test_full_coordinates_give_the_reference_accelerations(model):
    full = FastDynamics(model, coordinates="full")
    rng = np.random.default_rng(4)
    for x in random_states(model, count=2):
        u = random_input(model, rng)
        dx = full.rhs(0.0, full.from_reduced(x), u)
        n3 = 3 * model.n
        assert_close(evaluate(0.0, x, u, model).N_ddot.ravel(), dx[n3 : 2 * n3])
        N, N_dot = full.nodes(full.from_reduced(x))
        assert_close(np.concatenate(model.nodes(x)).ravel(), np.concatenate([N, N_dot]).ravel())


def test_batched_and_complex_step(model):
    """The batched form (the estimator's interface) and a complex-step derivative."""
    fast = FastDynamics(model)
    L = model.layout
    xs = list(random_states(model, count=3))
    u = model.input_at(0.5)
    q = np.stack([x[L.q].reshape(3, -1) for x in xs])
    q_dot = np.stack([x[L.q_dot].reshape(3, -1) for x in xs])
    omega = np.stack([model.wheel_speeds(x, u) for x in xs])
    for dyn in (fast, FastDynamics(model, kernel=False)):  # kernel loop and numpy batch
        eta2_ddot, N_ddot = dyn.accelerations(q, q_dot, omega, u[: model.alpha])
        for k, x in enumerate(xs):
            ev = evaluate(0.0, x, u, model)
            assert_close(ev.eta2_ddot, eta2_ddot[k])
            assert_close(ev.N_ddot, N_ddot[k])
    h, d = 1e-30, np.random.default_rng(5).normal(size=q.shape[1:])
    rest = u[: model.alpha]
    a_c, _ = fast.accelerations(q[0] + 1j * h * d, q_dot[0], omega[0], rest + 0j)
    eps = 1e-6
    a_p, _ = fast.accelerations(q[0] + eps * d, q_dot[0], omega[0], rest)
    a_m, _ = fast.accelerations(q[0] - eps * d, q_dot[0], omega[0], rest)
    central = (a_p - a_m) / (2 * eps)
    assert np.abs(a_c.imag / h - central).max() <= 1e-6 * max(1.0, np.abs(central).max())


@pytest.mark.parametrize("joined", [False, True], ids=["class-1", "class-2"])
def test_large_structures_sparse_path(joined):
    """Above the dense limit: sparse class-1 path and banded saddle-point path."""
    model = Model(prism_chain(140, joined=joined, string_mass_kg=0.0 if joined else 0.01))
    fast = FastDynamics(model)
    assert fast.kernel is None and fast.size > 400
    rng = np.random.default_rng(6)
    for x in random_states(model, count=2):
        u = random_input(model, rng)
        assert_close(rhs(0.0, x, u, model), fast.rhs(0.0, x, u))


def test_flattened_loop_is_a_clear_error():
    """The D-bar rhombus folded flat (all four bars collinear): the bar-length constraints
    of the closed loop are dependent; the kernel names the bar instead of returning inf."""
    model = Model(load_scene(SCENES[0]))
    assert model.scene.name == "dbar-gyro"
    fast = FastDynamics(model)
    # make test installs a C compiler, so the optional kernel must have been built: a silent
    # build failure would otherwise leave the compiled path untested.
    assert fast.kernel is not None, "compiled kernel not built: reinstall with a C compiler"
    flat = {"n1": [-0.3048, 0, 0], "n2": [0, 0, 0], "n3": [0.3048, 0, 0], "n4": [0, 0, 0]}
    N = np.array([flat[name] for name in model.structure.node_names], float).T
    x = model.state(N, np.zeros_like(N))
    with pytest.raises(SimulationError, match=r"t = 0.5 s: constraint system singular at b"):
        fast.rhs(0.5, x, model.input_at(0.0))
