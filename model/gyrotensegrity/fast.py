"""Fast right-hand side: the same dynamics as :func:`gyrotensegrity.dynamics.evaluate`,
with every constant factor precomputed and all constraint forces from one small solve.

Formulation (equal to Eqs. 53-68 of the reference path, to round-off). In coordinates ``z``
(3, m') with ``N = N_fix + z U^T`` (reduced order: ``U = U2``, ``z = eta2``; full order:
``U = I``, ``z = N``), bars are ``B = B_fix + z E^T`` with ``E = C_b U`` and strings
``S = S_fix + z E_s^T`` with ``E_s = C_s U``. With ``M = U^T M_s U`` the accelerations are::

    z_ddot = (f0 + (B mu^) E + Omega P_u^T) M^-1,      f0 = W U - S gamma^ E_s + G E

where ``G`` (3, beta) are the gyroscopic columns ``J_a omega_w b x b_dot / l`` (Eq. 34),
``mu`` (beta,) the bar force densities (the reference's ``lambda``, Eqs. 58/62 with Omega) and
``Omega`` (3, c) the joint multipliers of the full-order variant (``P_u = U^T P``; zero in
reduced order, where ``P^T U2 = 0``). ``mu`` and ``Omega`` follow from the constraints
``b_i . b_i_ddot = -|b_i_dot|^2`` and ``z_ddot P_u = 0``: a symmetric system of size
``beta + 3 c_u`` whose bar block is ``Y .* (B^T B)`` with the constant ``Y = E M^-1 E^T``.
For class-1 structures ``Y`` is diagonal and ``mu`` is explicit (cost linear in size); for
structures with joints the system is dense (small structures) or sparse (large ones, solved
as the sparse saddle-point system with ``M``).

The reference path (``dynamics.py``) stays the readable implementation the tests compare
against (tests/model/test_fast.py).
"""

import bisect

import numpy as np
import scipy.sparse as sp

from .errors import SceneError, SimulationError
from .model import Model
from .sparse_constraints import SparseConstraints

try:  # the optional compiled kernel (setup.py); the numpy path below is the fallback
    from . import _fastkernel
except ImportError:  # pragma: no cover - depends on the build
    _fastkernel = None
else:  # its matrix products through scipy's BLAS (the kernel's loops without it)
    from scipy.linalg import cython_blas

    try:
        _fastkernel.use_blas(cython_blas.__pyx_capi__["dgemm"])
    except (AttributeError, KeyError, ValueError):  # pragma: no cover - depends on scipy
        pass

DENSE_LIMIT = 100  # coordinates m' up to which the dense path (and the compiled kernel) is used
FULL_LIMIT = 400  # full coordinates with joints: dense only, up to this many coordinates


def _dense(a):
    return a.toarray() if sp.issparse(a) else np.asarray(a, dtype=float)


class _Right:
    """``X @ A`` for X of shape (..., k) and a constant A (k, l), dense or sparse."""

    def __init__(self, A, dense: bool):
        self.dense = dense
        self.A = _dense(A) if dense else None
        self.A_T = None if dense else sp.csr_matrix(A.T)
        self.l = A.shape[1]

    def __call__(self, X):
        if self.dense:
            return X @ self.A
        flat = X.reshape(-1, X.shape[-1])
        return np.asarray(self.A_T @ flat.T).T.reshape(X.shape[:-1] + (self.l,))


class FastDynamics:
    """Precomputed fast evaluation of a compiled model.

    Parameters
    ----------
    model : Model
    coordinates : {"reduced", "full"}
        ``"reduced"``: the model's state (``eta2``, Eq. 68), a drop-in for
        :func:`gyrotensegrity.rhs`. ``"full"``: all node coordinates ``N`` in the state and the
        joints held by multipliers (Eqs. 60-62), so joint errors can drift; state
        ``[vec(N) 3n | vec(N_dot) 3n | theta_w | omega_w of torque wheels]``, row by row.
    kernel : bool
        Use the compiled kernel when it is built and the structure is small (dense path).
    dense_limit : int, optional
        Largest ``m'`` for the dense path (default :data:`DENSE_LIMIT`); above it the sparse
        path (class 1: explicit bar forces; with joints: banded saddle-point solve).

    Notes
    -----
    Shapes: coordinates ``z`` are ``(..., 3, m')`` (any leading batch shape), where ``m'`` is
    ``model.m`` (reduced) or ``model.n`` (full).
    """

    def __init__(
        self, model: Model, coordinates: str = "reduced", kernel: bool = True, dense_limit=None
    ):
        if coordinates not in ("reduced", "full"):
            raise ValueError(f"coordinates must be 'reduced' or 'full', got {coordinates!r}")
        if model.rig is not None:
            raise SceneError(
                f"{model.scene.source}: rig_fidelity: FastDynamics is the paper's model only; "
                "simulate() and Stepper take the option's own fast path (fast_rig.FastRig)"
            )
        st = model.structure
        self.model, self.coordinates = model, coordinates
        self.beta, self.alpha = model.beta, model.alpha
        if coordinates == "reduced":
            U = model.U2
            N_fix = np.asarray(model.N_fixed_T).T
            P_u = np.zeros((model.m, 0))
        else:
            U = sp.identity(model.n, format="csr")
            N_fix = np.zeros((3, model.n))
            P_u = _dense(st.P)
        self.size = U.shape[1]  # m'
        limit = DENSE_LIMIT if dense_limit is None else dense_limit
        if coordinates == "full" and model.c:
            limit = FULL_LIMIT
        dense = self.size <= limit
        self.U_T = _Right(U.T, dense)
        self.N_fix = N_fix
        E = sp.csr_matrix(st.C_b @ U)
        E_s = sp.csr_matrix(st.C_s @ U)
        # (bars | strings) images of z, with the constant offsets of the positions
        self.EE_T = _Right(sp.vstack([E, E_s]).T, dense)
        self.off = np.hstack([np.asarray(C @ N_fix.T).T for C in (st.C_b, st.C_s)])
        # reduced forces: (G + B mu^ | S gamma^) @ [E; -E_s]
        self.E_force = _Right(sp.vstack([E, -E_s]), dense)
        self.WU = np.asarray(U.T @ np.asarray(model.W).T).T  # (3, m')
        self.k_s, self.c_s = model.k_s, model.c_s
        self._wheels(model)
        self.state_size = 6 * self.size + model.layout.n_wheels + model.layout.n_torque
        self.kernel = None
        if dense:
            self._dense_mass(model, U, E, P_u)
            if kernel and _fastkernel is not None:
                self._kernel_constants()
        else:
            self._sparse_mass(model, U, E, P_u)

    # -- constants --------------------------------------------------------------------------
    def _wheels(self, model):
        gyro = "gyroscopic" in model.terms
        wb, tq = model.wheel_bars, model.torque_wheels
        self.wheel_bars, self.torque_wheels, self.n_wheels = wb, tq, len(wb)
        self.gyro_coef = model.J_a[wb] / model.l[wb] if gyro else np.zeros(len(wb))
        self.speed_mask = np.zeros(len(wb))
        self.speed_mask[model.speed_wheels] = 1.0
        self.inv_J3 = 1.0 / model.J3[wb[tq]]  # spin acceleration per unit torque, 1/(kg m^2)

    def _wheel_matrices(self):
        """Dense wheel maps for the compiled kernel: spins -> gyro factor per bar,
        torque-wheel states -> spins, wheel inputs -> spin accelerations."""
        nw, ntq, tq = self.n_wheels, len(self.torque_wheels), self.torque_wheels
        to_bar = np.zeros((nw, self.beta))
        to_bar[np.arange(nw), self.wheel_bars] = self.gyro_coef
        select = np.zeros((ntq, nw))
        select[np.arange(ntq), tq] = 1.0
        gain = np.zeros((nw, ntq))
        gain[tq, np.arange(ntq)] = self.inv_J3
        return [to_bar, select, self.speed_mask, gain]

    def _dense_mass(self, model, U, E, P_u):
        """Dense constants: M^-1, E M^-1, Y = E M^-1 E^T and the joint blocks."""
        M_inv = np.linalg.inv((U.T @ model.M_s @ U).toarray())
        M_inv = 0.5 * (M_inv + M_inv.T)
        E_d = E.toarray()
        E_Minv = E_d @ M_inv  # (beta, m')
        Y = E_Minv @ E_d.T
        self.c_u = P_u.shape[1]
        self.Minv, self.Minv_ET, self.E_Minv = (_Right(a, True) for a in (M_inv, E_Minv.T, E_Minv))
        self.P_u, self.Pu_Minv = P_u, P_u.T @ M_inv  # (m', c_u), (c_u, m')
        self.X = self.Pu_Minv @ E_d.T  # (c_u, beta)
        self.A3 = np.kron(np.eye(3), self.Pu_Minv @ P_u)  # joint block, (3 c_u, 3 c_u)
        off = Y - np.diag(np.diag(Y))
        self.diagonal = self.c_u == 0 and not np.any(np.abs(off) > 1e-14 * np.abs(Y).max())
        self.Y, self.Y_diag = Y, np.diag(Y).copy()
        self.sparse = None

    def _sparse_mass(self, model, U, E, P_u):
        """Large structures. Without constraints ``M^-1 = U^T M_s^-1 U`` is sparse (Eq. 47)
        and ``Y`` diagonal: everything stays sparse and linear in size. With joints:
        the saddle-point system (:class:`.sparse_constraints.SparseConstraints`)."""
        self.c_u = P_u.shape[1]
        if self.c_u:
            raise ValueError(
                f"full coordinates with joints are supported up to {FULL_LIMIT} "
                f"coordinates; this model has {self.size}"
            )
        self.diagonal = model.c == 0
        if self.diagonal:
            M_inv = sp.csr_matrix(U.T @ model.M_s_inv @ U)
            E_Minv = sp.csr_matrix(E @ M_inv)
            self.Y_diag = np.asarray(E_Minv.multiply(E).sum(axis=1)).ravel()
            self.Minv = _Right(M_inv, False)
            self.Minv_ET, self.E_Minv = _Right(E_Minv.T, False), _Right(E_Minv, False)
            self.sparse = None
        else:
            self.sparse = SparseConstraints(sp.csc_matrix(U.T @ model.M_s @ U), E)

    def _kernel_constants(self):
        """Pack the dense constants for the compiled kernel (order of ``layout`` in C)."""
        parts = [self.EE_T.A, self.off, self.k_s, self.c_s, *self._wheel_matrices()]
        parts += [self.WU, self.E_force.A]
        parts += [self.Minv.A, self.Minv_ET.A, self.E_Minv.A, self.Y, self.P_u, self.Pu_Minv]
        parts += [self.X, self.A3]
        self._consts = np.concatenate([np.asarray(p, float).ravel() for p in parts])
        nw, ntq = self.n_wheels, len(self.torque_wheels)
        self._dims = np.array(
            [self.size, self.beta, self.alpha, nw, ntq, self.c_u, int(self.diagonal)], np.int64
        )
        k, nb = self.beta + self.alpha, self.beta + 3 * self.c_u
        self._work = np.empty(9 * k + 6 * self.size + 3 * self.beta + nw + nb + nb * nb)
        self._x = np.zeros(self.state_size)  # wheel angles stay 0: no force depends on them
        self._u = np.empty(self.alpha + nw)
        self._dx = np.empty(self.state_size)
        self.kernel = _fastkernel

    # -- evaluation -------------------------------------------------------------------------
    def accelerations(self, q, q_dot, omega_w, rest):
        """Accelerations of a (batch of) state(s); the interface of the estimator's
        ``BatchDynamics`` (complex-step safe: slack tests use real parts).

        Parameters
        ----------
        q, q_dot : ndarray, shape (..., 3, m'), m and m/s (real or complex)
        omega_w : ndarray, shape (..., n_w), rad/s
        rest : ndarray, shape (..., alpha) or (alpha,), m
            String rest lengths (real or complex).

        Returns
        -------
        z_ddot : ndarray, shape (..., 3, m'), m/s^2
        N_ddot : ndarray, shape (..., 3, n), m/s^2
        """
        z_ddot = self.reduced_accelerations(q, q_dot, omega_w, rest)
        return z_ddot, self.node_values(z_ddot)

    def reduced_accelerations(self, q, q_dot, omega_w, rest):
        """:meth:`accelerations` without the node accelerations: ``z_ddot`` (..., 3, m'),
        m/s^2 (a filter's prediction needs no more)."""
        self.check_spins(omega_w)
        if self.kernel is not None and _all_real(q, q_dot, omega_w, rest):
            return self._kernel_accelerations(q, q_dot, omega_w, rest)
        return self._accelerations(q, q_dot, omega_w, rest)

    def check_spins(self, omega_w):
        """The model's omitted-term check on wheel spins (..., n_w), rad/s (no-op when the
        model omits nothing)."""
        if self.model.omitted:
            spin = np.abs(np.reshape(omega_w, (-1, self.n_wheels))).max(axis=0, initial=0.0)
            self.model.check_omitted(spin[self.torque_wheels], spin * self.speed_mask)

    def _kernel_accelerations(self, q, q_dot, omega_w, rest):
        """Real states through the compiled kernel, one call per state of the batch."""
        lead = q.shape[:-2]
        k, nw, alpha = 3 * self.size, self.n_wheels, self.alpha
        q, q_dot = q.reshape(-1, k), q_dot.reshape(-1, k)
        count = len(q)
        omega_w, rest = _rows(omega_w, lead, nw), _rows(rest, lead, alpha)
        out = np.empty((count, k))
        # the kernel's state and input, filled in place: a batch of one is the filter's
        # prediction, called four times per step, where allocations cost more than the kernel
        x, u, dx = self._x, self._u, self._dx
        for i in range(count):
            w, r = omega_w[min(i, len(omega_w) - 1)], rest[min(i, len(rest) - 1)]
            x[:k], x[k : 2 * k] = q[i], q_dot[i]
            x[2 * k + nw :] = w[self.torque_wheels]
            u[:alpha], u[alpha:] = r, w  # speed wheels read their spin from u
            status = self.kernel.rhs(self._consts, self._dims, x, u, dx, self._work)
            if status:
                self._singular(float("nan"), status - 1)
            out[i] = dx[k : 2 * k]
        return out.reshape(lead + (3, self.size))

    def wheel_acceleration(self, u, dtype=float):
        """Spin acceleration of every wheel (n_w,), rad/s^2: torque / J_3 for torque wheels."""
        out = np.zeros(self.n_wheels, dtype=dtype)
        out[self.torque_wheels] = u[self.alpha + self.torque_wheels] * self.inv_J3
        return out

    def node_values(self, z):
        """``z U^T`` (no offset): node velocities or accelerations (..., 3, n)."""
        return self.U_T(z)

    def _accelerations(self, q, q_dot, omega_w, rest):
        beta = self.beta
        Y6 = self.EE_T(np.concatenate([q, q_dot], axis=-2))  # (..., 6, beta + alpha)
        Y6[..., :3, :] += self.off
        pos, vel = Y6[..., :3, :], Y6[..., 3:, :]
        B, B_dot = pos[..., :beta], vel[..., :beta]
        S = pos[..., beta:]
        sums = _colsum(pos[..., None, :, :] * Y6.reshape(Y6.shape[:-2] + (2, 3, -1)))
        b2 = sums[..., 0, :beta]
        s = np.sqrt(sums[..., 0, beta:])
        tension = self.k_s * (s - rest) + self.c_s * (sums[..., 1, beta:] / s)
        taut = (s.real > np.real(rest)) & (tension.real > 0.0)
        gamma = np.where(taut, tension / s, 0.0)
        factor = np.zeros(omega_w.shape[:-1] + (beta,), dtype=omega_w.dtype)
        factor[..., self.wheel_bars] = self.gyro_coef * omega_w  # J_a omega_w / l per bar
        G = _cross(B, B_dot) * factor[..., None, :]
        cols = np.concatenate([G, S * gamma[..., None, :]], axis=-1)
        f0 = self.WU + self.E_force(cols)  # (..., 3, m')
        bd2 = _colsum(B_dot * B_dot)
        if self.sparse is not None:
            return self.sparse.solve(f0, B, b2, bd2)
        a0 = self.Minv(f0)
        r = -bd2 - _colsum(B * self.Minv_ET(f0))
        if self.diagonal:
            return a0 + self.E_Minv(B * (r / (self.Y_diag * b2))[..., None, :])
        Z = self.Y * (np.swapaxes(B, -1, -2) @ B)
        if not self.c_u:
            mu = np.linalg.solve(Z, r[..., None])[..., 0]
            return a0 + self.E_Minv(B * mu[..., None, :])
        return self._with_joints(a0, B, Z, r)

    def _with_joints(self, a0, B, Z, r):
        """Bars and joints together (full coordinates): the symmetric (beta + 3c) system."""
        beta, c = self.beta, self.c_u
        lead = B.shape[:-2]
        Zbo = (np.swapaxes(B, -1, -2)[..., :, :, None] * self.X.T[:, None, :]).reshape(
            lead + (beta, 3 * c)
        )
        top = np.concatenate([Z, Zbo], axis=-1)
        bottom = np.concatenate(
            [np.swapaxes(Zbo, -1, -2), np.broadcast_to(self.A3, lead + self.A3.shape)], axis=-1
        )
        K = np.concatenate([top, bottom], axis=-2)
        rhs = np.concatenate([r, -(a0 @ self.P_u).reshape(lead + (3 * c,))], axis=-1)
        sol = np.linalg.solve(K, rhs[..., None])[..., 0]
        mu, Omega = sol[..., :beta], sol[..., beta:].reshape(lead + (3, c))
        return a0 + self.E_Minv(B * mu[..., None, :]) + Omega @ self.Pu_Minv

    # -- state-vector interface ------------------------------------------------------------
    def split(self, x, u):
        """Coordinates, their rates and the wheel spins of a state (single state).

        Returns
        -------
        q, q_dot : ndarray, shape (3, m'); omega_w : ndarray, shape (n_w,), rad/s
        """
        k = 3 * self.size
        q = x[:k].reshape(3, self.size)
        q_dot = x[k : 2 * k].reshape(3, self.size)
        omega_w = self.speed_mask * u[self.alpha :]
        omega_w[self.torque_wheels] = x[2 * k + self.n_wheels :]
        return q, q_dot, omega_w

    def rhs(self, t, x, u):
        """dx/dt, shape (state_size,), of the state ``x`` (layout of ``coordinates``).

        Raises
        ------
        SimulationError
            When the constraint system is singular (compiled kernel), naming the bar.
        PrunedTermError
            When a wheel spins or is driven on a model built with ``omit=("gyroscopic",)``.
        """
        if self.kernel is not None:
            self._check_omitted(x, u)
            out = np.empty(self.state_size)
            status = self.kernel.rhs(
                self._consts,
                self._dims,
                np.ascontiguousarray(x, float),
                np.ascontiguousarray(u, float),
                out,
                self._work,
            )
            if status:
                self._singular(t, status - 1)
            return out
        return self.rhs_numpy(t, x, u)

    def _singular(self, t, pivot):
        m = self.model
        if pivot < self.beta:
            member = m.scene.bars[pivot].name
            why = "bar directions nearly dependent (collinear bars) or zero length"
        else:
            member = m.structure.constraint_names[(pivot - self.beta) % self.c_u]
            why = "joint constraints dependent"
        raise SimulationError(
            f"t = {t:.6g} s: constraint system singular at {member} ({why})", t, member
        )

    def rhs_numpy(self, t, x, u):
        """dx/dt by the numpy path (the compiled kernel's reference and fallback)."""
        self._check_omitted(x, u)
        q, q_dot, omega_w = self.split(x, u)
        z_ddot = self._accelerations(q, q_dot, omega_w, u[: self.alpha])
        k = 3 * self.size
        spin = u[self.alpha + self.torque_wheels] * self.inv_J3
        return np.concatenate([x[k : 2 * k], z_ddot.ravel(), omega_w, spin])

    def _check_omitted(self, x, u):
        """The model's omitted-term check on a state of this object's layout."""
        if self.model.omitted:
            start = 6 * self.size + self.n_wheels  # after q, q_dot and the wheel angles
            spin = x[start : start + len(self.torque_wheels)]
            self.model.check_omitted(spin, u[self.alpha :])

    def project(self, x, rtol=1e-15, iterations=6):
        """``projection.project`` (min-norm Gauss-Newton onto the bar lengths, then the
        velocities onto b.b_dot = 0) with dense constants; reduced coordinates only.

        Parameters
        ----------
        x : ndarray, shape (state_size,)

        Returns
        -------
        ndarray, shape (state_size,): the projected state
        """
        if self.coordinates != "reduced" or not self.EE_T.dense or self.beta == 0:
            from .projection import project

            return project(self.model, x)
        x = x.copy()
        k, beta = 3 * self.size, self.beta
        E = self.EE_T.A[:, :beta].T  # (beta, m')
        EEt = E @ E.T
        off, l2 = self.off[:, :beta], self.model.l**2
        q = x[:k].reshape(3, self.size)
        for _ in range(iterations):
            B = off + q @ E.T
            g = _colsum(B * B) - l2
            if np.max(np.abs(g) / l2) <= rtol:
                break
            mu = np.linalg.solve(4.0 * EEt * (B.T @ B), g)
            q = q - 2.0 * (B * mu) @ E
        x[:k] = q.ravel()
        B = off + q @ E.T
        q_dot = x[k : 2 * k].reshape(3, self.size)
        nu = np.linalg.solve(EEt * (B.T @ B), _colsum(B * (q_dot @ E.T)))
        x[k : 2 * k] = (q_dot - (B * nu) @ E).ravel()
        return x

    def nodes(self, x):
        """Node positions and velocities (3, n), m and m/s, of a state."""
        k = 3 * self.size
        q = x[:k].reshape(3, self.size)
        return self.N_fix + self.node_values(q), self.node_values(x[k : 2 * k].reshape(3, -1))

    def from_reduced(self, x):
        """The state in this object's coordinates of a reduced-order model state ``x``."""
        if self.coordinates == "reduced":
            return np.asarray(x, float).copy()
        m = self.model
        N, N_dot = m.nodes(x)
        return np.concatenate([N.ravel(), N_dot.ravel(), x[m.layout.theta], x[m.layout.omega]])


def fast_rhs(t, x, u, params: FastDynamics):
    """dx/dt with the common callback signature ``f(t, x, u, params)``; ``params`` is a
    :class:`FastDynamics` (drop-in for ``rhs(t, x, u, model)``)."""
    return params.rhs(t, x, u)


def _rows(a, lead: tuple, width: int):
    """Per-state rows of an input: (1, width) when one serves the whole batch ``lead``, else
    (count, width)."""
    a = np.asarray(a)
    count = int(np.prod(lead))
    if a.ndim == 1:
        return a.reshape(1, width)
    if a.shape[:-1] != lead:
        a = np.broadcast_to(a, lead + (width,))
    return a.reshape(count, width)


def _all_real(*arrays) -> bool:
    """No complex array among ``arrays`` (the complex step takes the numpy path)."""
    return not any(np.iscomplexobj(a) for a in arrays)


def _colsum(X):
    """Sum over the 3 rows of (..., 3, k): cheaper than a reduction over a strided axis."""
    return X[..., 0, :] + X[..., 1, :] + X[..., 2, :]


def _cross(a, b):
    """Column-wise cross product of (..., 3, k) arrays (complex-step safe, no np.cross)."""
    return np.stack(
        [
            a[..., 1, :] * b[..., 2, :] - a[..., 2, :] * b[..., 1, :],
            a[..., 2, :] * b[..., 0, :] - a[..., 0, :] * b[..., 2, :],
            a[..., 0, :] * b[..., 1, :] - a[..., 1, :] * b[..., 0, :],
        ],
        axis=-2,
    )


class InputTable:
    """The scene's scheduled input ``u(t)`` (as ``Model.input_at``) from one table lookup.

    Every schedule is piecewise linear between its own points, hence linear between the
    points of all schedules together: the values at the union of the times are tabulated
    once, so an evaluation is one ``searchsorted`` and one interpolation of the whole vector.

    Parameters
    ----------
    model : Model
    """

    def __init__(self, model: Model):
        schedules = model.rest_schedules + model.wheel_schedules
        self.t = np.unique(np.concatenate([s.t for s in schedules] + [np.zeros(1)]))
        self.table = np.array([[s(t) for s in schedules] for t in self.t])  # (k, inputs)
        self.slope = np.diff(self.table, axis=0) / np.diff(self.t)[:, None]
        self.times = self.t.tolist()

    def __call__(self, t: float) -> np.ndarray:
        """u (alpha + n_w,) at time t, s."""
        j = bisect.bisect_right(self.times, t) - 1
        if j < 0 or j >= len(self.slope):
            return self.table[0 if j < 0 else -1].copy()
        return self.table[j] + (t - self.times[j]) * self.slope[j]
