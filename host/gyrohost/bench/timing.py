"""Micro-timings: right-hand side and step cost against structure size, the EKF budget.

Every figure is the minimum over several repeats of the mean over a loop (the machine is
shared; the minimum is the least disturbed measurement).
"""

import time

import numpy as np

from gyrotensegrity import Model, rhs
from gyrotensegrity.fast import FastDynamics
from gyrotensegrity.generators import prism_chain
from gyrotensegrity.integrators import RK4

SIZES_FULL = (1, 3, 10, 34, 67, 100, 200, 334, 1000)  # prisms: 3 to 3,000 bars
SIZES_QUICK = (1, 10, 40, 80)


def best_time(fn, repeats=5, target_s=0.05):
    """Minimum over ``repeats`` of the mean time of ``fn()`` in a loop of ~target_s, s."""
    fn()
    t0 = time.perf_counter()
    fn()
    once = max(time.perf_counter() - t0, 1e-7)
    loops = max(1, int(target_s / once))
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(loops):
            fn()
        best = min(best, (time.perf_counter() - t0) / loops)
    return best


def rhs_costs(model: Model, x, u, repeats=5, target_s=0.05, reference=True):
    """Costs (s) of one evaluation: reference, fast numpy path, compiled kernel (if built)."""
    out = {}
    if reference:
        out["reference"] = best_time(lambda: rhs(0.0, x, u, model), repeats, target_s)
    numpy_path = FastDynamics(model, kernel=False)
    out["fast_numpy"] = best_time(lambda: numpy_path.rhs(0.0, x, u), repeats, target_s)
    fast = FastDynamics(model)
    if fast.kernel is not None:
        out["fast_kernel"] = best_time(lambda: fast.rhs(0.0, x, u), repeats, target_s)
    out["fast"] = out.get("fast_kernel", out["fast_numpy"])

    def step():
        RK4.step(lambda t, y: fast.rhs(t, y, u), 0.0, x, 1e-4)

    out["rk4_step"] = best_time(step, repeats, target_s)
    return out


def scaling(quick: bool, log=print) -> list:
    """rhs and RK4 step cost of prism chains (class 1 and class 2) against the bar count."""
    rows = []
    for joined in (False, True):
        for prisms in SIZES_QUICK if quick else SIZES_FULL:
            model = Model(prism_chain(prisms, joined=joined))
            x, u = model.initial_state(), model.input_at(0.0)
            cost = rhs_costs(
                model, x, u, repeats=3 if quick else 5, target_s=0.01 if quick else 0.05
            )
            rows.append({"bars": model.beta, "joined": joined, "coordinates": 3 * model.m, **cost})
            log(
                f"  {model.beta:5d} bars {'class-2' if joined else 'class-1'}: "
                f"rhs {cost['fast'] * 1e6:9.1f} us (reference {cost['reference'] * 1e6:9.1f} us)"
                f", RK4 step {cost['rk4_step'] * 1e6:9.1f} us"
            )
    return rows


def fit_exponent(rows, key, joined, min_bars=100):
    """Slope of log(cost) against log(bars) over the sizes with at least ``min_bars`` bars."""
    pts = [(r["bars"], r[key]) for r in rows if r["joined"] == joined and r["bars"] >= min_bars]
    if len(pts) < 2:
        return None
    b, c = np.log(np.array(pts)).T
    return float(np.polyfit(b, c, 1)[0])


def ekf_budget(model: Model, repeats=5, target_s=0.05, dt=0.01):
    """What the EKF needs per IMU sample (``dt`` s): one RK4 process step over dt (4 batched
    derivative calls, as the estimator's lean model), and the Jacobian ``A = df/dx`` by one
    batched complex-step call over all dynamic states (positions, velocities, torque-wheel
    spins, rest lengths); for :class:`FastDynamics`, the estimator's dynamics, against its own
    numpy path as the baseline (``kernel=False``: batched numpy for every call)."""

    L, m, alpha = model.layout, model.m, model.alpha
    x, u = model.initial_state(), model.input_at(0.0)
    nd = 6 * m + L.n_torque + alpha
    omega0 = model.wheel_speeds(x, u)[None, :]
    q0, qd0 = x[L.q].reshape(1, 3, m), x[L.q_dot].reshape(1, 3, m)
    rest0 = u[None, :alpha]
    # one complex perturbation per dynamic state, batched
    Q, QD = np.tile(q0 + 0j, (nd, 1, 1)), np.tile(qd0 + 0j, (nd, 1, 1))
    W, R = np.tile(omega0 + 0j, (nd, 1)), np.tile(rest0 + 0j, (nd, 1))
    idx, h = np.arange(3 * m), 1e-30j
    Q.reshape(nd, -1)[idx, idx] += h
    QD.reshape(nd, -1)[3 * m + idx, idx] += h
    W[6 * m + np.arange(L.n_torque), model.torque_wheels] += h
    R[6 * m + L.n_torque + np.arange(alpha), np.arange(alpha)] += h
    out = {}
    for name, dyn in (
        ("FastDynamics, numpy path", FastDynamics(model, kernel=False)),
        ("FastDynamics", FastDynamics(model)),
    ):

        def step(dyn=dyn):
            q, qd = q0, qd0
            for _ in range(4):
                a, _ = dyn.accelerations(q, qd, omega0, rest0)
                q, qd = q + 0.5 * dt * qd, qd + 0.5 * dt * a

        def jac(dyn=dyn):
            dyn.accelerations(Q, QD, W, R)

        out[name] = {
            "process_step_s": best_time(step, repeats, target_s),
            "jacobian_s": best_time(jac, repeats, target_s),
            "states": nd,
        }
    fast = FastDynamics(model)
    out["FastDynamics"]["kernel_rk4_step_s"] = best_time(
        lambda: RK4.step(lambda t, y: fast.rhs(t, y, u), 0.0, x, dt), repeats, target_s
    )
    return out
