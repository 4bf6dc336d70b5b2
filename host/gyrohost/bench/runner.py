"""Timed integration of one model variant with one integrator setting, and its diagnostics.

The timed part is the integration alone (right-hand sides, integrator, input schedule);
diagnostics are computed afterwards from the recorded samples and are not timed.
"""

import time
from dataclasses import dataclass, field

import numpy as np

from gyrotensegrity import Model, diagnostics
from gyrotensegrity.fast import FastDynamics, InputTable
from gyrotensegrity.integrators import ADAPTIVE, RK4, adaptive_solver

from .errors import RunStopped


@dataclass
class Variant:
    """A model variant: a compiled model in reduced or full coordinates.

    Attributes
    ----------
    name : str
    model : Model
    coordinates : {"reduced", "full"}
    """

    name: str
    model: Model
    coordinates: str = "reduced"
    fast: FastDynamics = field(init=False)

    def __post_init__(self):
        self.fast = FastDynamics(self.model, self.coordinates)
        self.inputs = InputTable(self.model)

    def x0(self):
        return self.fast.from_reduced(self.model.initial_state())

    def f(self, t, x):
        return self.fast.rhs(t, x, self.inputs(t))


@dataclass
class Trajectory:
    """Samples of one run: ``N`` (K, 3, n) m, ``N_dot`` (K, 3, n) m/s, ``omega`` (K, n_w)."""

    t_s: np.ndarray
    N: np.ndarray
    N_dot: np.ndarray
    omega: np.ndarray
    wall_s: float
    nfev: int
    failure: str | None = None


def integrate(
    variant: Variant,
    method: str,
    setting: float,
    duration: float,
    sample_dt: float,
    budget_s: float = np.inf,
) -> Trajectory:
    """Integrate ``variant`` over ``duration`` s, sampling every ``sample_dt`` s.

    Parameters
    ----------
    method : str
        ``rk4``, ``rk4-projected`` (``setting`` = step, s) or an adaptive scipy method
        (``setting`` = rtol; atol = 1e-3 rtol, m).
    budget_s : float, s
        Wall-time budget; a run that exceeds it stops with ``failure = "budget"``.
    """
    f, fast = variant.f, variant.fast
    samples = np.arange(int(round(duration / sample_dt)) + 1) * sample_dt
    states = [variant.x0()]
    counter = {"n": 0}

    def counted(t, x):
        counter["n"] += 1
        return f(t, x)

    failure = None
    start = time.perf_counter()
    try:
        if method in ADAPTIVE:
            _adaptive(variant, method, setting, counted, samples, states, start, budget_s)
        else:
            _fixed(variant, method, setting, counted, samples, states, start, budget_s)
    except RunStopped as stop:
        failure = str(stop)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        failure = f"{type(exc).__name__}: {exc}"
    wall = time.perf_counter() - start
    k = len(states)
    nodes = [fast.nodes(x) for x in states]
    omega = [fast.split(x, variant.inputs(t))[2] for t, x in zip(samples[:k], states, strict=True)]
    return Trajectory(
        samples[:k],
        np.array([n[0] for n in nodes]),
        np.array([n[1] for n in nodes]),
        np.array(omega),
        wall,
        counter["n"],
        failure,
    )


def _check(x, start, budget_s, t):
    if not np.all(np.isfinite(x)):
        raise RunStopped(f"non-finite state at t = {t:.4g} s")
    if time.perf_counter() - start > budget_s:
        raise RunStopped("budget")


def _fixed(variant, method, dt, f, samples, states, start, budget_s):
    sample_dt = samples[1] - samples[0]
    steps = max(1, int(np.ceil(sample_dt / dt - 1e-9)))
    h = sample_dt / steps
    x = states[0]
    projected = method == "rk4-projected"
    for k in range(1, len(samples)):
        t0 = samples[k - 1]
        for j in range(steps):
            x = RK4.step(f, t0 + j * h, x, h)
            if projected:
                x = variant.fast.project(x)
        _check(x, start, budget_s, samples[k])
        states.append(x)


def _adaptive(variant, method, rtol, f, samples, states, start, budget_s):
    solver = adaptive_solver(method, f, 0.0, states[0], samples[-1], rtol, 1e-3 * rtol)
    k = 1
    while k < len(samples):
        message = solver.step()
        if solver.status == "failed":
            raise RunStopped(f"{method} failed at t = {solver.t:.4g} s: {message}")
        _check(solver.y, start, budget_s, solver.t)
        dense = solver.dense_output()
        while k < len(samples) and samples[k] <= solver.t:
            states.append(dense(samples[k]))
            k += 1


def errors(variant: Variant, run: Trajectory, reference: Trajectory) -> dict:
    """Accuracy figures of a run against a tight reference of the same physics.

    Returns
    -------
    dict
        ``node_error_m`` (max over samples and nodes), ``bar_length_error`` (max relative),
        ``joint_error_m``, ``energy_drift`` (relative, None when the scene does work),
        ``momentum_drift`` (relative to the largest sum of body momentum magnitudes of the
        reference, :func:`gyrotensegrity.diagnostics.momentum_scale`).
    """
    m = variant.model
    k = len(run.t_s)
    node_err = float(np.max(np.abs(run.N - reference.N[:k]))) if k else np.inf
    bar = max(float(np.max(np.abs(diagnostics.bar_length_error(m, N)) / m.l)) for N in run.N)
    joint = max(float(np.max(diagnostics.joint_error(m, N), initial=0.0)) for N in run.N)
    H = np.array(
        [
            diagnostics.angular_momentum(m, N, Nd, w)
            for N, Nd, w in zip(run.N, run.N_dot, run.omega, strict=True)
        ]
    )
    ref_states = zip(reference.N, reference.N_dot, reference.omega, strict=True)
    scale = max(max(diagnostics.momentum_scale(m, N, Nd, w) for N, Nd, w in ref_states), 1e-300)
    energy = None
    if _conservative(m):
        rest = variant.inputs(0.0)[: m.alpha]
        e = np.array(
            [
                diagnostics.energy(m, N, Nd, w, rest)["total"]
                for N, Nd, w in zip(run.N, run.N_dot, run.omega, strict=True)
            ]
        )
        energy = float(np.max(np.abs(e - e[0])) / max(abs(e[0]), 1e-300))
    return {
        "node_error_m": node_err,
        "bar_length_error": bar,
        "joint_error_m": joint,
        "energy_drift": energy,
        "momentum_drift": float(np.max(np.linalg.norm(H - H[0], axis=1)) / scale),
    }


def run_drifts(model: Model, run) -> dict:
    """Invariant drifts of a run file (:func:`gyrotensegrity.simulate`'s ``Run``).

    Returns
    -------
    dict
        ``momentum_drift``: largest change of the total angular momentum relative to the
        largest sum of body momentum magnitudes (:func:`gyrotensegrity.diagnostics.momentum_scale`);
        ``energy_drift``: largest change of the total energy relative to the initial one, None
        when the scene does work (schedules, damping, driven wheels).
    """
    H = run["angular_momentum"]
    wheels = run["omega_w"][:, model.wheel_bars]  # the run file holds one column per bar
    states = zip(run["N"], run["N_dot"], wheels, strict=True)
    scale = max(max(diagnostics.momentum_scale(model, N, Nd, w) for N, Nd, w in states), 1e-300)
    energy = None
    if _conservative(model):
        e = run["energy"]
        energy = float(np.max(np.abs(e - e[0])) / max(abs(e[0]), 1e-300))
    return {
        "energy_drift": energy,
        "momentum_drift": float(np.max(np.linalg.norm(H - H[0], axis=1)) / scale),
    }


def _conservative(model: Model) -> bool:
    """Energy is conserved: constant rest lengths, no damping, no driven wheels."""
    constant = all(len(s.t) == 1 for s in model.rest_schedules)
    driven = any(
        mode == "speed" or np.any(s.value)
        for s, mode in zip(model.wheel_schedules, model.wheel_modes, strict=True)
    )
    return constant and not np.any(model.c_s > 0) and not driven
