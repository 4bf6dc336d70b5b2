"""Running a model: ``simulate`` (whole runs with diagnostics) and ``Stepper`` (step by step).

Inputs come from a controller with the common callback signature ``control(t, x, u, params)``:
it receives the scene's scheduled input ``u`` (rest lengths, wheel inputs) and returns the
input to apply. Without a controller the scene's schedules drive the model.
"""

import platform
import time

import numpy as np
import scipy

from . import __version__, diagnostics, engagement
from .dynamics import rhs
from .errors import SimulationError
from .integrators import ADAPTIVE, FIXED_STEP, adaptive_solver, check_name, fixed_step
from .model import Model
from .runfile import Run


def dynamics_of(model: Model, fast: bool):
    """The right-hand side ``f(t, x, u)`` and the projector (None: the reference one) of the
    reference path or of the fast path."""
    if fast and model.rig is not None:
        from .fast_rig import FastRig

        return FastRig(model).rhs, None
    if fast:
        from .fast import FastDynamics

        fd = FastDynamics(model)
        return fd.rhs, fd.project
    return (lambda t, x, u: rhs(t, x, u, model)), None


RK4_STABLE = 2.5  # |omega dt| below the RK4 stability limit on the imaginary axis (2.83)
EXPLICIT_STABLE = 3.0  # |omega h| an explicit adaptive step reaches on a mode it need not resolve
# Steps per unit of the motion's own time scale tau for an explicit adaptive method at rtol:
# h = C tau rtol^(1/p), p the order of its error control. C measured on the prism with bar and
# wheel masses of 1 kg ... 1e-9 kg, rtol 1e-4 ... 1e-12 (docs/performance.md): the estimate is
# within a factor of 2 of the steps taken.
EXPLICIT_ACCURACY = {"dop853": (8, 0.25), "rk45": (5, 0.5)}
MAX_STEPS = 2_000_000  # explicit adaptive runs that would need more steps are refused


def explicit_steps(model: Model, integrator: str, duration: float, rtol: float, x0, u0):
    """Estimated steps of an explicit adaptive integrator over ``duration``.

    Two bounds, the larger wins. Stability: a step covers at most ``EXPLICIT_STABLE`` radians
    of the fastest oscillation ``omega`` (:func:`diagnostics.highest_frequency`), enough when
    that mode is stiff and barely excited. Accuracy: the motion itself must be resolved to
    ``rtol``; its time scale ``tau = sqrt(L / a)``, with ``L`` the structure's extent and ``a``
    the largest node acceleration at the start. When the stiffest string carries the motion
    (node masses tiny for the string stiffness), ``1 / tau`` approaches ``omega`` and accuracy
    costs far more steps than stability.

    Parameters
    ----------
    integrator : {"dop853", "rk45"}
    duration : float, s
    rtol : float
    x0 : ndarray, shape (layout.size,)
    u0 : ndarray, shape (alpha + n_w,)

    Returns
    -------
    steps : float
    why : str
        The bound that sets it, naming its member (the string or wheel bar for stability, the
        node for accuracy).
    member : str
    """
    omega, stiff = diagnostics.highest_frequency(model)
    with np.errstate(all="ignore"):  # a singular start is the run's to report, with its member
        q_ddot = rhs(0.0, x0, u0, model)[model.layout.q_dot].reshape(3, model.m)
    N_ddot = np.asarray((model.U2 @ q_ddot.T).T)  # rhs: any model, rig fidelity included
    N, _ = model.nodes(x0)
    accel = np.nan_to_num(np.linalg.norm(N_ddot, axis=0), nan=0.0, posinf=0.0)
    node = int(np.argmax(accel))
    extent = float(np.max(np.ptp(N, axis=1)))
    order, c = EXPLICIT_ACCURACY[integrator]
    rate = np.sqrt(accel[node] / extent) / (c * rtol ** (1.0 / order)) if extent > 0 else 0.0
    if omega / EXPLICIT_STABLE >= rate:
        why = f"stiff: {stiff} oscillates at up to {omega:.3g} rad/s"
        return omega * duration / EXPLICIT_STABLE, why, stiff
    name = model.structure.node_names[node]
    why = (
        f"node {name} accelerates at {accel[node]:.3g} m/s^2, so the motion changes within "
        f"{1.0 / np.sqrt(accel[node] / extent):.3g} s and rtol {rtol:g} needs short steps"
        + (f" ({stiff} oscillates at up to {omega:.3g} rad/s)" if stiff else "")
    )
    return rate * duration, why, name


def stable_step(model: Model, dt: float) -> float:
    """The largest RK4 step of at most ``dt`` (s) that keeps the model's fastest oscillation
    within RK4's stability limit (``omega h <= RK4_STABLE``), s."""
    omega, _ = diagnostics.highest_frequency(model)
    # a hair inside the limit, so that omega h <= RK4_STABLE holds in floating point too
    return dt if omega * dt <= RK4_STABLE else RK4_STABLE / omega * (1.0 - 1e-9)


def check_step(
    model: Model, integrator: str, dt: float, duration: float, rtol=None, x0=None, u0=None
) -> None:
    """Refuse an explicit integrator that cannot resolve the model's fastest motion.

    Parameters
    ----------
    dt : float, s
        Step of a fixed-step integrator.
    rtol : float, optional
        Tolerance of an explicit adaptive integrator; with ``x0`` (state) and ``u0`` (input at
        t = 0) it enables the step estimate of :func:`explicit_steps`.

    Raises
    ------
    SimulationError
        At t = 0, naming the string, wheel bar or node that makes the run too costly and
        suggesting the remedies.
    """
    if integrator in FIXED_STEP:
        omega, member = diagnostics.highest_frequency(model)
        if omega * dt <= RK4_STABLE:
            return
        raise SimulationError(
            f"t = 0 s: stiff: {member} oscillates at up to {omega:.3g} rad/s; {integrator} "
            f"needs dt <= {RK4_STABLE / omega:.3g} s; use an implicit integrator (radau or "
            "bdf) or a smaller dt",
            0.0,
            member,
        )
    if integrator not in EXPLICIT_ACCURACY or x0 is None:
        return
    steps, why, member = explicit_steps(model, integrator, duration, rtol, x0, u0)
    if steps > MAX_STEPS:
        raise SimulationError(
            f"t = 0 s: {why}; {integrator} needs about {steps:.3g} steps; use an implicit "
            "integrator (radau or bdf), a looser rtol or a shorter run",
            0.0,
            member,
        )


def nonfinite_member(model: Model, x) -> str | None:
    """Name of the first node (or "wheels") whose state entry is not finite, else None."""
    if np.all(np.isfinite(x)):
        return None
    N, N_dot = model.nodes(x)  # sparse U2: a bad coordinate spoils only its own nodes
    bad = np.flatnonzero(~np.all(np.isfinite(N) & np.isfinite(N_dot), axis=0))
    return model.structure.node_names[bad[0]] if bad.size else "wheels"


def _input_function(model: Model, control, fast=False):
    if fast:
        from .fast import InputTable

        input_at = InputTable(model)
    else:
        input_at = model.input_at
    if control is None:
        return lambda t, x: input_at(t)
    return lambda t, x: np.asarray(control(t, x, input_at(t), model), float)


class _Recorder:
    """Collects the output samples, runs the diagnostics and stops a failing run."""

    def __init__(self, model: Model, constraint_tolerance: float):
        self.model = model
        self.tol = constraint_tolerance
        self.rows = {k: [] for k in ("t", "N", "N_dot", "omega_w", "theta_w", "rest_length")}
        self.rows |= {k: [] for k in ("bar_length_error", "joint_error", "energy", "H")}

    def add(self, t, x, u):
        m = self.model
        N, N_dot = m.nodes(x)
        omega = m.wheel_speeds(x, u)
        self._check_finite(t, x, N, N_dot)
        rest = u[: m.alpha]
        bar_err = diagnostics.bar_length_error(m, N)
        joint_err = diagnostics.joint_error(m, N)
        self._check_constraints(t, bar_err, joint_err)
        for key, value in (
            ("t", t),
            ("N", N),
            ("N_dot", N_dot),
            ("omega_w", diagnostics.wheel_speeds_per_bar(m, omega)),
            ("theta_w", diagnostics.wheel_speeds_per_bar(m, x[m.layout.theta])),
            ("rest_length", rest),
            ("bar_length_error", bar_err),
            ("joint_error", joint_err),
            ("energy", diagnostics.energy(m, N, N_dot, omega, rest)["total"]),
            ("H", diagnostics.angular_momentum(m, N, N_dot, omega)),
        ):
            self.rows[key].append(value)

    def _fail(self, message, t, member):
        raise SimulationError(f"t = {t:.6g} s: {message}", t, member)

    def _check_finite(self, t, x, N, N_dot):
        m = self.model
        for what, X in (("position", N), ("velocity", N_dot)):
            bad = np.flatnonzero(~np.all(np.isfinite(X), axis=0))
            if bad.size:
                name = m.structure.node_names[bad[0]]
                self._fail(f"node {name} {what} is not finite", t, name)
        if not np.all(np.isfinite(x)):
            self._fail("wheel state is not finite", t, "wheels")

    def _check_constraints(self, t, bar_err, joint_err):
        m = self.model
        if m.beta and np.max(np.abs(bar_err)) > self.tol:
            i = int(np.argmax(np.abs(bar_err)))
            name = m.scene.bars[i].name
            self._fail(
                f"bar {name} length error {bar_err[i]:.3g} m exceeds {self.tol:g} m", t, name
            )
        if m.c and np.max(joint_err) > self.tol:
            j = int(np.argmax(joint_err))
            name = m.structure.constraint_names[j]
            self._fail(f"{name}: error {joint_err[j]:.3g} m exceeds {self.tol:g} m", t, name)

    def run(self, meta) -> Run:
        m, st = self.model, self.model.structure
        r = {k: np.array(v) for k, v in self.rows.items()}
        arrays = {
            "t": r["t"],
            "N": r["N"],
            "N_dot": r["N_dot"],
            "node_names": np.array(st.node_names),
            "omega_w": r["omega_w"],
            "theta_w": r["theta_w"],
            "C_b": st.C_b.toarray(),
            "C_s": st.C_s.toarray(),
            "m_t": m.m_t,
            "J_t": m.J_t,
            "J_a": m.J_a,
            "bar_length": m.l,
            "m_node": m.m_node,
            "string_stiffness": m.k_s,
            "string_damping": m.c_s,
            "rest_length": r["rest_length"].reshape(len(r["t"]), m.alpha),
            "gravity": m.scene.gravity,
            "W": m.W,
            "bar_length_error": r["bar_length_error"].reshape(len(r["t"]), m.beta),
            "joint_error": r["joint_error"].reshape(len(r["t"]), m.c),
            "energy": r["energy"],
            "angular_momentum": r["H"].reshape(len(r["t"]), 3),
            "scene": np.array(m.scene.to_json()),
        }
        return Run(arrays, meta)


def simulate(
    model: Model,
    duration=None,
    integrator=None,
    dt=None,
    rtol=None,
    atol=None,
    sample_dt=None,
    constraint_tolerance=None,
    control=None,
    x0=None,
    progress=None,
    fast=False,
) -> Run:
    """Simulate ``model`` from its initial state and record samples every ``sample_dt``.

    Parameters default to the scene's ``[simulation]`` table and ``scene.duration``.

    Parameters
    ----------
    duration : float, s
    integrator : str, one of :data:`gyrotensegrity.integrators.NAMES`
    dt : float, s
        Step of the fixed-step integrators (rounded down so that it divides ``sample_dt``).
    rtol, atol : float
        Tolerances of the adaptive integrators.
    sample_dt : float, s
    constraint_tolerance : float, m
        The run stops with :class:`SimulationError` when a bar-length or joint error exceeds it.
    control : callable ``control(t, x, u, params) -> u``, optional
    x0 : ndarray, optional
        Initial state (default ``model.initial_state()``).
    progress : callable ``progress(t, duration)``, optional
    fast : bool
        Evaluate the dynamics by :mod:`gyrotensegrity.fast` (same equations, to round-off)
        instead of the reference :func:`~gyrotensegrity.rhs`.

    Raises
    ------
    SimulationError
        With the time and member at fault; ``exc.partial`` holds the run up to then. Also
        before the start when an explicit integrator cannot resolve the stiffest string or
        wheel (:func:`check_step`).
    """
    s = model.scene.simulation
    duration = model.scene.duration if duration is None else float(duration)
    integrator = check_name(integrator or s.integrator)
    dt, rtol, atol = dt or s.dt, rtol or s.rtol, atol or s.atol
    sample_dt = sample_dt or s.sample_dt
    tol = constraint_tolerance or s.constraint_tolerance
    u_of = _input_function(model, control, fast)
    x = model.initial_state() if x0 is None else np.asarray(x0, float)
    n_samples = int(np.floor(duration / sample_dt + 1e-9))
    samples = np.arange(n_samples + 1) * sample_dt
    rec = _Recorder(model, tol)
    meta = _run_meta(model, integrator, rtol, atol, sample_dt, tol, fast)
    dyn, projector = dynamics_of(model, fast)

    def f(t, x):
        return dyn(t, x, u_of(t, x))

    report = (lambda t: progress(t, duration)) if progress else (lambda t: None)
    start = time.perf_counter()
    try:
        u0 = u_of(0.0, x)
        check_step(model, integrator, dt, duration, rtol, x, u0)
        rec.add(0.0, x, u0)
        if integrator in FIXED_STEP:
            h = sample_dt / max(1, int(np.ceil(sample_dt / dt - 1e-9)))  # divides sample_dt
            meta["dt"] = h
            _fixed_steps(model, integrator, f, projector, x, samples, h, rec, u_of, report)
        else:
            solver = adaptive_solver(
                integrator, _finite_rates(model, f), 0.0, x, samples[-1], rtol, atol
            )
            _adaptive_steps(model, integrator, f, solver, samples, rec, u_of, report)
            meta["nfev"] = solver.nfev
    except SimulationError as exc:
        meta["wall_time_s"] = time.perf_counter() - start
        meta["error"] = str(exc)
        exc.partial = rec.run(meta)
        raise
    meta["wall_time_s"] = time.perf_counter() - start
    return rec.run(meta)


def _run_meta(model, integrator, rtol, atol, sample_dt, tol, fast) -> dict:
    """What a run file records of how it was made (docs/model.md#run-files-npz)."""
    return {
        "integrator": integrator,
        "rtol": rtol,
        "atol": atol,
        "sample_dt": sample_dt,
        "constraint_tolerance": tol,
        "model": model.describe(),
        "terms": sorted(model.terms),
        "versions": {
            "gyrotensegrity": __version__,
            "numpy": np.__version__,
            "scipy": scipy.__version__,
            "python": platform.python_version(),
        },
        "fast": bool(fast),
    }


def _finite_rates(model, f):
    """``f`` that raises :class:`SimulationError` on a non-finite rate: scipy's adaptive solvers
    loop forever on a NaN error estimate, so the run stops at the source."""

    def checked(t, x):
        dx = f(t, x)
        if not np.isfinite(dx).all():
            member = nonfinite_member(model, x) or nonfinite_member(model, dx) or "wheels"
            raise SimulationError(
                f"t = {t:.6g} s: {member}: rate not finite (singular constraints or a "
                "diverging state)",
                t,
                member,
            )
        return dx

    return checked


def _fixed_steps(model, integrator, f, projector, x, samples, h, rec, u_of, report) -> None:
    """Step a fixed-step integrator by ``h`` (s, a divisor of the sample period) through
    ``samples``, recording each and reporting its time."""
    steps = int(round((samples[1] - samples[0]) / h)) if len(samples) > 1 else 0
    for k in range(1, len(samples)):
        t = samples[k - 1]
        for j in range(steps):
            x = fixed_step(integrator, model, f, t + j * h, x, h, projector)
        rec.add(samples[k], x, u_of(samples[k], x))
        report(samples[k])


def _adaptive_steps(model, integrator, f, solver, samples, rec, u_of, report) -> None:
    """Step an adaptive ``solver`` past every sample, recording each from its dense output and
    reporting the solver's time."""
    k = 1
    while k < len(samples):
        if solver.status != "running":
            raise SimulationError(
                f"t = {solver.t:.6g} s: integrator {integrator} failed: {solver.message}"
                if hasattr(solver, "message")
                else f"integrator {integrator} stopped",
                solver.t,
                "integrator",
            )
        message = solver.step()
        if solver.status == "failed":
            _adaptive_failure(model, f, solver, integrator, message)
        dense = solver.dense_output()
        while k < len(samples) and samples[k] <= solver.t:
            xs = dense(samples[k])
            rec.add(samples[k], xs, u_of(samples[k], xs))
            k += 1
        report(solver.t)


def _adaptive_failure(model, f, solver, integrator, message):
    """Raise the clearest error for a failed adaptive step: a non-finite state or derivative
    names its node; a collapsed step size on an explicit method suggests stiffness."""
    t, x = solver.t, solver.y
    member = nonfinite_member(model, x)
    try:
        dx = f(t, x)
    except SimulationError:
        raise
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        raise SimulationError(f"t = {t:.6g} s: dynamics failed: {exc}", t, "dynamics") from None
    member = member or nonfinite_member(model, dx)
    if member:
        raise SimulationError(
            f"t = {t:.6g} s: {member}: state or its rate is not finite", t, member
        )
    hint = "; the model is stiff here: use radau or bdf" if integrator not in IMPLICIT else ""
    raise SimulationError(
        f"t = {t:.6g} s: integrator {integrator} failed: {message}{hint}", t, "integrator"
    )


IMPLICIT = tuple(name for name in ADAPTIVE if name in ("radau", "bdf"))


class Stepper:
    """Step the model with inputs given at each step (the simulated rig's truth model).

    The input is held over each step (zero-order hold), or, given its value at the step's end
    too, follows the straight line between the two (first-order hold: a device's output that
    moves on within the step, as a servo's or a wheel's, is not held back in steps). The step is
    divided into RK4 substeps of at most ``max_dt``, each split where a string goes taut (its
    force jumps there, :mod:`.engagement`).

    Parameters
    ----------
    model : Model
    x0 : ndarray, optional
        Initial state (default ``model.initial_state()``).
    max_dt : float, s
    project : bool
        Project onto the bar-length constraints after every substep (``rk4-projected``).
    fast : bool
        Use the fast path (:mod:`gyrotensegrity.fast`) for the dynamics.

    Examples
    --------
    >>> stepper = Stepper(model)
    >>> u = model.pack_input(rest_length=[0.4, 0.43], wheel=[75.0, -75.0, -75.0, 75.0])
    >>> x = stepper.step(0.01, u)
    """

    def __init__(self, model: Model, x0=None, t0=0.0, max_dt=1e-3, project=False, fast=False):
        self.model = model
        check_step(model, "rk4", max_dt, 0.0)
        self.dynamics, self.projector = dynamics_of(model, fast)
        self.x = model.initial_state() if x0 is None else np.asarray(x0, float).copy()
        self.t = float(t0)
        self.max_dt = float(max_dt)
        self.method = "rk4-projected" if project else "rk4"
        self.tautening = engagement.Tautening(model)

    def step(self, dt, u=None, u_end=None):
        """Advance by ``dt`` seconds under input ``u`` (default: the scene's input at ``t``),
        held, or with ``u_end`` given, moving in a straight line from ``u`` to ``u_end``.

        Returns
        -------
        x : ndarray, the new state
        """
        if not dt > 0.0:
            raise ValueError(f"step dt must be positive, got {dt}")
        u = self.model.input_at(self.t) if u is None else np.asarray(u, float)
        n = max(1, int(np.ceil(dt / self.max_dt - 1e-9)))
        h = dt / n
        t0, du = self.t, None if u_end is None else (np.asarray(u_end, float) - u) / dt

        def u_at(t):
            return u if du is None else u + (t - t0) * du

        def f(t, x):
            return self.dynamics(t, x, u_at(t))

        for j in range(n):
            self.x = self._substep(f, u_at, self.t + j * h, self.x, h)
        self.t += dt
        member = nonfinite_member(self.model, self.x)
        if member:
            raise SimulationError(
                f"t = {self.t:.6g} s: state is not finite at {member}", self.t, member
            )
        return self.x

    def _substep(self, f, u_at, t, x, h):
        """One RK4 substep of ``h`` s from ``x`` at ``t``, ended where a string goes taut and
        stepped on from there (each split leaves one more string taut)."""
        for _ in range(self.model.alpha + 1):
            x_end = self._rk4(f, t, x, h)
            share = self._taut_share(f, u_at, (t, x, h), x_end)
            if share is None:
                break
            x, t, h = self._rk4(f, t, x, share * h), t + share * h, (1.0 - share) * h
        return x_end

    def _taut_share(self, f, u_at, piece, x_end):
        """The share of the substep ``piece`` (t, x, h) that ends at ``x_end`` at which a string
        goes taut (:meth:`.engagement.Tautening.share`), or None."""
        t, x, h = piece
        start = (x, u_at(t))
        if not self.tautening.between(start, (x_end, u_at(t + h))):
            return None

        def at(share):
            return self._rk4(f, t, x, share * h), u_at(t + share * h)

        return self.tautening.share(start, at)

    def _rk4(self, f, t, x, h):
        return fixed_step(self.method, self.model, f, t, x, h, self.projector)

    def nodes(self):
        """Node positions and velocities (3, n), m and m/s."""
        return self.model.nodes(self.x)
