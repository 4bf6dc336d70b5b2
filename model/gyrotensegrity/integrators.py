"""Integrators chosen by name.

Fixed step: ``rk4`` (classic Runge-Kutta) and ``rk4-projected`` (RK4, then projection of the
state onto the bar-length constraints after every step, see :mod:`.projection`).
Adaptive (scipy): ``dop853``, ``rk45`` (explicit), ``radau``, ``bdf`` (implicit, for stiff strings).
"""

from dataclasses import dataclass

import numpy as np

from .projection import project

FIXED_STEP = ("rk4", "rk4-projected")
ADAPTIVE = {"dop853": "DOP853", "rk45": "RK45", "radau": "Radau", "bdf": "BDF"}
"""Adaptive method name -> its class in ``scipy.integrate``, imported when one is asked for: a
process that only steps (the simulated rig's truth, the estimator) starts a third of a second
sooner without it."""
NAMES = FIXED_STEP + tuple(ADAPTIVE)


@dataclass(frozen=True)
class ExplicitRungeKutta:
    """A fixed-step explicit Runge-Kutta method given by its Butcher tableau.

    Attributes
    ----------
    a : ndarray, shape (s, s), strictly lower triangular
    b : ndarray, shape (s,)
    c : ndarray, shape (s,)
    """

    name: str
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray

    def __post_init__(self):
        # nonzero coefficients as Python floats: the stages skip exact zeros (adding 0 * k
        # changes nothing) and avoid numpy-scalar overhead per product
        stages = [
            [(j, float(self.a[i, j])) for j in range(i) if self.a[i, j]] for i in range(len(self.b))
        ]
        object.__setattr__(self, "_stages", stages)
        object.__setattr__(self, "_weights", [(i, float(w)) for i, w in enumerate(self.b) if w])
        object.__setattr__(self, "_nodes", [float(c) for c in self.c])

    def step(self, f, t, x, dt):
        """One step of ``dx/dt = f(t, x)`` from (t, x) over dt; returns the new state."""
        k = []
        for i, terms in enumerate(self._stages):
            xi = x + dt * _combine(terms, k) if i else x
            k.append(f(t + self._nodes[i] * dt, xi))
        return x + dt * _combine(self._weights, k)


def _combine(terms, k):
    """sum of a_j k_j over the (j, a_j) pairs, in order."""
    (j, a), *rest = terms
    total = a * k[j]
    for j, a in rest:
        total += a * k[j]
    return total


RK4 = ExplicitRungeKutta(
    "rk4",
    a=np.array([[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1.0, 0]]),
    b=np.array([1, 2, 2, 1]) / 6.0,
    c=np.array([0, 0.5, 0.5, 1.0]),
)


def check_name(name: str) -> str:
    if name not in NAMES:
        raise ValueError(f"unknown integrator '{name}' (choose one of: {', '.join(NAMES)})")
    return name


def fixed_step(name: str, model, f, t, x, dt, projector=None):
    """One fixed step of the named method, with the projection for ``rk4-projected``
    (``projector(x)``, default :func:`.projection.project` of ``model``)."""
    x = RK4.step(f, t, x, dt)
    if name != "rk4-projected":
        return x
    return projector(x) if projector is not None else project(model, x)


def adaptive_solver(name: str, f, t0, x0, t_bound, rtol, atol, max_step=np.inf):
    """A scipy ``OdeSolver`` (dense output enabled through ``dense_output()``)."""
    from scipy import integrate

    solver = getattr(integrate, ADAPTIVE[name])
    return solver(f, t0, x0, t_bound, rtol=rtol, atol=atol, max_step=max_step)
