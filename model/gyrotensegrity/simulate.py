"""Running a model: ``simulate`` (whole runs with diagnostics) and ``Stepper`` (step by step).

Inputs come from a controller with the common callback signature ``control(t, x, u, params)``:
it receives the scene's scheduled input ``u`` (rest lengths, wheel inputs) and returns the
input to apply. Without a controller the scene's schedules drive the model.
"""

import json
import platform
import time

import numpy as np
import scipy

from . import __version__, diagnostics
from .dynamics import rhs
from .errors import SimulationError
from .integrators import FIXED_STEP, adaptive_solver, check_name, fixed_step
from .model import Model
from .runfile import Run


def _input_function(model: Model, control):
    if control is None:
        return lambda t, x: model.input_at(t)
    return lambda t, x: np.asarray(control(t, x, model.input_at(t), model), float)


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

    Raises
    ------
    SimulationError
        With the time and member at fault; ``exc.partial`` holds the run up to then.
    """
    s = model.scene.simulation
    duration = model.scene.duration if duration is None else float(duration)
    integrator = check_name(integrator or s.integrator)
    dt, rtol, atol = dt or s.dt, rtol or s.rtol, atol or s.atol
    sample_dt = sample_dt or s.sample_dt
    tol = constraint_tolerance or s.constraint_tolerance
    u_of = _input_function(model, control)
    x = model.initial_state() if x0 is None else np.asarray(x0, float)
    n_samples = int(np.floor(duration / sample_dt + 1e-9))
    samples = np.arange(n_samples + 1) * sample_dt
    rec = _Recorder(model, tol)
    meta = {
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
    }

    def f(t, x):
        return rhs(t, x, u_of(t, x), model)

    start = time.perf_counter()
    try:
        rec.add(0.0, x, u_of(0.0, x))
        if integrator in FIXED_STEP:
            steps = max(1, int(np.ceil(sample_dt / dt - 1e-9)))
            meta["dt"] = h = sample_dt / steps
            for k in range(1, len(samples)):
                t = samples[k - 1]
                for j in range(steps):
                    x = fixed_step(integrator, model, f, t + j * h, x, h)
                rec.add(samples[k], x, u_of(samples[k], x))
                if progress:
                    progress(samples[k], duration)
        else:
            solver = adaptive_solver(integrator, f, 0.0, x, samples[-1], rtol, atol)
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
                    raise SimulationError(
                        f"t = {solver.t:.6g} s: integrator {integrator} failed: {message}",
                        solver.t,
                        "integrator",
                    )
                dense = solver.dense_output()
                while k < len(samples) and samples[k] <= solver.t:
                    xs = dense(samples[k])
                    rec.add(samples[k], xs, u_of(samples[k], xs))
                    k += 1
                if progress:
                    progress(solver.t, duration)
            meta["nfev"] = solver.nfev
    except SimulationError as exc:
        meta["wall_time_s"] = time.perf_counter() - start
        meta["error"] = str(exc)
        exc.partial = rec.run(meta)
        raise
    meta["wall_time_s"] = time.perf_counter() - start
    return rec.run(meta)


class Stepper:
    """Step the model with inputs given at each step (the simulated rig's truth model).

    The input is held over each step (zero-order hold) and the step is divided into RK4
    substeps of at most ``max_dt``.

    Parameters
    ----------
    model : Model
    x0 : ndarray, optional
        Initial state (default ``model.initial_state()``).
    max_dt : float, s
    project : bool
        Project onto the bar-length constraints after every substep (``rk4-projected``).

    Examples
    --------
    >>> stepper = Stepper(model)
    >>> u = model.pack_input(rest_length=[0.4, 0.43], wheel=[75.0, -75.0, -75.0, 75.0])
    >>> x = stepper.step(0.01, u)
    """

    def __init__(self, model: Model, x0=None, t0=0.0, max_dt=1e-3, project=False):
        self.model = model
        self.x = model.initial_state() if x0 is None else np.asarray(x0, float).copy()
        self.t = float(t0)
        self.max_dt = float(max_dt)
        self.method = "rk4-projected" if project else "rk4"

    def step(self, dt, u=None):
        """Advance by ``dt`` seconds under input ``u`` (default: the scene's input at ``t``).

        Returns
        -------
        x : ndarray, the new state
        """
        if not dt > 0.0:
            raise ValueError(f"step dt must be positive, got {dt}")
        u = self.model.input_at(self.t) if u is None else np.asarray(u, float)
        n = max(1, int(np.ceil(dt / self.max_dt - 1e-9)))
        h = dt / n

        def f(t, x):
            return rhs(t, x, u, self.model)

        for j in range(n):
            self.x = fixed_step(self.method, self.model, f, self.t + j * h, self.x, h)
        self.t += dt
        if not np.all(np.isfinite(self.x)):
            raise SimulationError(f"t = {self.t:.6g} s: state is not finite", self.t, "state")
        return self.x

    def nodes(self):
        """Node positions and velocities (3, n), m and m/s."""
        return self.model.nodes(self.x)

    def json_meta(self) -> str:
        return json.dumps({"t": self.t, "method": self.method, "max_dt": self.max_dt})
