"""The identified parameters' errors as the filter's states: random constants whose priors are
how well the identification knows them.

A scene identified from one recording is known to its 1-sigma, and a filter that takes it as
exact is overconfident wherever the motion makes those errors count: the strings' stiffness and
damping errors become force errors in proportion to the strings' stretch and rate, largest in
the paper's long pulls, which the noise fitted over a quiet recording does not cover. The
servos' goal delay is fitted on one run as well, but a run's delay is where the phase of its
ticks falls in the rig's latency spread, the same for the whole run and different in the next:
a ramp's rest lengths then lag by ``speed x delay`` for the whole run, which a per-goal jitter
does not describe.

The wheels' J3, identified to a few tenths of a percent, sets how far the spinning wheels turn
the structure: an error of its 1-sigma, taken as exact, can leave a run's NEES several times
its dof. All three are carried as states (``layout.string_errors``, ``layout.j3_error``,
``layout.goal_delay``), with the dynamics linear in them about the scene's values (their
errors are a few percent, a fraction of a millisecond): each prediction step adds
``G theta`` to the state and the matching terms to the covariance, ``G`` the step's response
to them (:func:`string_columns`, :func:`j3_column`, :func:`goal_delay_column`). The
measurements see them through the states they move; by default the filter considers them
(:mod:`.consider`: their estimate stays 0, ``G theta`` adds nothing, the covariance's terms
carry them).

- A string pulls with ``k e + c ds/dt`` (``e`` its stretch, the damping while it shortens):
  a relative error ``d_k`` of the stiffness is the force of a rest-length error ``-e d_k``,
  one ``d_c`` of the damping that of ``-(c/k) (ds/dt) d_c``; through the step's response to the
  rest lengths (:meth:`.process_noise.ProcessNoise.taut_columns`), for taut strings only.
- A goal delay ``d`` shifts the rest lengths' path by ``d``: a rest length is ``-d r_dot`` off
  (``r_dot`` its rate under the lag); over a step that offset moves from ``-d F_rr r_dot0`` (the
  step's map of the start's, under the goals before) to ``-d r_dot1``.
"""

from dataclasses import replace

import numpy as np

from gyrotensegrity.fast import FastDynamics
from gyrotensegrity.model import Model

from .motor_reaction import MotorReaction


def string_columns(process, x, x_next, F, dt) -> np.ndarray:
    """The node motion's response (6 m, 2) over a step of ``dt`` s from ``x`` to ``x_next``
    (n,) (``F`` its Jacobian, at least (6 m, 6 m)) to the stiffness's and the damping's
    relative errors: the trapezoid rule ``dt/2 (F b(x) + b(x_next))`` over the step, ``b`` the
    accelerations' response, for the damping's force follows the strings' rates, which the
    stiff strings turn within a step."""
    L = process.layout
    weights, margin = _force_weights(process, x)
    a = process.taut_rest_columns(x, margin)
    n = L.q_dot.stop
    G = F[:n, L.q_dot] @ a @ weights
    G[L.q_dot] += a @ _force_weights(process, x_next)[0]
    return 0.5 * dt * G


def j3_column(response, x, x_next, F, u, dt) -> np.ndarray:
    """The node motion's response (6 m,) over a step of ``dt`` s from ``x`` to ``x_next`` (n,)
    under ``u`` (``F`` its Jacobian) to the wheels' J3 relative error: the trapezoid rule
    ``dt/2 (F b(x) + b(x_next))``, ``b`` the accelerations' ``response`` (a
    :class:`J3Response`)."""
    L = response.process.layout
    g = F[: L.q_dot.stop, L.q_dot] @ response(x, u)
    g[L.q_dot] += response(x_next, u)
    return 0.5 * dt * g


J3_STEP = 1e-4
"""Relative step of the wheels' J3 for the accelerations' response to it (:class:`J3Response`):
the response is nearly linear in J3, so a forward difference errs by about this share of it,
and its round-off is 1e-12 of the accelerations."""


class J3Response:
    """The accelerations' response (3 m,) m/s^2 of ``process`` (a
    :class:`.process_model.ProcessModel`) at a filter state to a relative error of the wheels'
    J3 (one log factor on every wheel's, as identify fits it): a forward difference of
    :data:`J3_STEP` through a twin of its dynamics whose wheels' J3 are stepped (their axial
    inertia, the gyroscopic terms and the motors' reaction)."""

    def __init__(self, process):
        self.process = process
        scene, J3 = process.model.scene, process.model.J3
        bars = [
            b if b.wheel is None else replace(b, wheel=replace(b.wheel, J3=(1 + J3_STEP) * J3[i]))
            for i, b in enumerate(scene.bars)
        ]
        model = Model(replace(scene, bars=bars), omit=tuple(process.model.omitted))
        self.dyn = FastDynamics(model)
        self.reaction = MotorReaction(self.dyn) if process.reaction is not None else None

    def __call__(self, x, u) -> np.ndarray:
        p = self.process
        X = np.asarray(x, float)[None, : p.layout.n_dynamic]
        base = p.derivative(X, u)[0, p.layout.q_dot]
        own = p.dyn, p.reaction  # the same evaluation, with the twin's dynamics in place
        p.dyn, p.reaction = self.dyn, self.reaction
        try:
            stepped = p.derivative(X, u)[0, p.layout.q_dot]
        finally:
            p.dyn, p.reaction = own
        return (stepped - base) / J3_STEP


def _force_weights(process, x) -> tuple[np.ndarray, np.ndarray]:
    """Each string's force error (alpha, 2) per relative error of the stiffness and the
    damping at ``x``, as rest-length errors: ``-e`` and ``-(c/k) ds/dt`` (the damping while the
    string shortens), 0 for a slack string; and the strings' tension margins (alpha,) m
    (:meth:`.process_noise.ProcessNoise.tension_margins`' values)."""
    L, dyn = process.layout, process.dyn
    s, s_dot = process.string_lengths(x[: L.n_dynamic])
    stretch, damping = s - x[L.rest], dyn.c_s / dyn.k_s * s_dot
    margin = stretch + np.minimum(damping, 0.0)
    taut = margin > 0.0
    W = np.zeros((L.n_strings, 2))
    W[:, 0] = -stretch * taut
    W[:, 1] = -damping * (taut & (damping < 0.0))
    return W, margin


def goal_delay_column(process, x, x_next, u, u_before, F) -> np.ndarray:
    """The rest lengths' response (alpha,) m/s over a step from ``x`` to ``x_next`` (n,) under
    the input ``u`` (``F`` its Jacobian; ``u_before`` the input of the step before) to an error
    of the goal delay: ``-(r_dot1 - F_rr r_dot0)``, ``r_dot0`` the rate at the start under the
    goals before, for a later goal step moves the rest lengths later. Under goals that hold
    over both steps it is 0; at a goal step ``g - g0`` at the start, ``-F_rr (g - g0) / lag``."""
    rest = process.layout.rest
    r_dot1 = process.servo_speed(x_next[rest], u)
    return -(r_dot1 - np.diag(F[rest, rest]) * process.servo_speed(x[rest], u_before))


class ParamErrors:
    """Adds the parameter errors' part of a prediction step (module docstring) to the steps of
    ``process`` (a :class:`.process_model.ProcessModel`) for the filter layout ``layout``."""

    def __init__(self, process, layout):
        self.process = process
        self.layout = L = layout
        self.motion = np.arange(L.q.start, L.q_dot.stop)
        self.rest = np.arange(L.rest.start, L.rest.stop)
        self.columns = np.arange(L.params.start, L.params.stop)
        self.j3 = J3Response(process) if L.n_j3_error else None
        self._u_before = None  # the input of the last step

    def step(self, x, x_next, P_next, F, u, dt):
        """``x_next`` (n,) and ``P_next`` (n, n), a step of ``dt`` s from ``x`` under ``u``
        with the parameter errors held, with their part added (``F`` the step's Jacobian over
        at least the dynamic states)."""
        L, cols = self.layout, self.columns
        G = np.zeros((L.size, len(cols)))
        if L.n_string_errors:
            k = L.string_errors.start - L.params.start
            G[self.motion, k : k + 2] = string_columns(self.process, x, x_next, F, dt)
        if L.n_j3_error:
            k = L.j3_error.start - L.params.start
            G[self.motion, k] = j3_column(self.j3, x, x_next, F, u, dt)
        if L.n_goal_delay:
            before = u if self._u_before is None else self._u_before
            G[self.rest, -1] = goal_delay_column(self.process, x, x_next, u, before, F)
            self._u_before = np.array(u, float)
        x_next = x_next + G @ x[cols]
        # F_full P F_full^T for F_full = F (+) I plus G in the parameters' columns: the step's
        # cross terms C = P_next[:, cols] (the held parameters' columns of F P F^T)
        C = P_next[:, cols]
        GC = G @ C.T
        P_next = P_next + GC + GC.T + G @ P_next[np.ix_(cols, cols)] @ G.T
        return x_next, P_next
