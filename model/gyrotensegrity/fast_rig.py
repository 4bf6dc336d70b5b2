"""Fast right-hand side of the rig-fidelity model: the dynamics of
:meth:`gyrotensegrity.rigfidelity.RigFidelity.rhs` in the compiled kernel (``rig_rhs`` in
``_fastkernel.c``), equal to it to round-off (tests/model/test_fast_rig.py).

The reference path spends its time in numpy's and scipy's per-call overhead on arrays of a few
entries (sparse products, the sparse LU of the reduced mass matrix, ``lstsq``), not in
arithmetic: a numpy rewrite with dense constants halves it, the kernel takes it to a few
percent (reports/attitude_closed_loop.md). The kernel forms the same equations with dense
constants: node maps ``B = B_off + q E_b^T``, forces ``f = W U2 + cols [E_b; -E_s]``, ``M^-1``
over the generalized speeds ``[vec(eta2_dot), omega_ax]``, the bar-length and hinge rows of
``G``. It solves ``K mu = -gamma - G M^-1 Q`` (``K = G M^-1 G^T``) by Cholesky with complete
pivoting, as LAPACK's ``dpstrf``, up to the first pivot at or below :data:`rigfidelity.RCOND` of
the largest: a closed loop of hinges makes ``K`` singular, and the rows beyond the numerical rank
are the redundant ones, whose multipliers it sets to zero. On a state that keeps the
constraints (the equations are then consistent) that solves the same equations as the
reference's least-squares multipliers, and the accelerations ``M^-1 (Q + G^T mu)`` are unique.
Near a configuration where a singular value of ``K`` crosses the cut the two rank decisions may
differ, as any two would.
"""

import numpy as np

from .rigfidelity import RCOND

try:  # the optional compiled kernel (setup.py); without it the reference path runs
    from . import _fastkernel
except ImportError:  # pragma: no cover - depends on the build
    _fastkernel = None


def _dense(a):
    return a.toarray() if hasattr(a, "toarray") else np.asarray(a, dtype=float)


class FastRig:
    """The rig-fidelity right-hand side of a compiled model through the kernel.

    Parameters
    ----------
    model : Model
        A model with the rig-fidelity option (``model.rig`` not None).

    Attributes
    ----------
    kernel : module or None
        The compiled kernel; None when it is not built (then :meth:`rhs` is the reference's).
    """

    def __init__(self, model):
        if model.rig is None:
            raise ValueError(f"{model.scene.source}: FastRig needs the rig-fidelity option")
        self.model, self.kernel = model, _fastkernel
        self.state_size = model.layout.size
        if self.kernel is None:  # pragma: no cover - depends on the build
            return
        self._consts = self._constants(model)
        self._dims = self._sizes(model)
        self._work = np.empty(self.kernel.rig_work(self._dims))

    @staticmethod
    def _constants(model):
        """The kernel's constants in the order of ``rig_layout`` in C."""
        rig, st = model.rig, model.structure
        U2 = _dense(model.U2)
        C = np.vstack([_dense(st.C_b), _dense(st.C_s)])  # (beta + alpha, n)
        E = C @ U2
        E_force = np.vstack([E[: model.beta], -E[model.beta :]])
        speed = np.zeros(len(model.wheel_bars))
        speed[model.speed_wheels] = 1.0
        M_inv = np.linalg.inv(model.M_red.toarray())
        wheel_bars = model.wheel_bars
        parts = [E.T, np.asarray(model.N_fixed_T).T @ C.T, model.k_s, model.c_s]
        parts += [np.asarray(model.W) @ U2, E_force, 1.0 / model.l**3, model.J3[wheel_bars]]
        parts += [speed, 0.5 * (M_inv + M_inv.T), rig.J_s]
        parts += [1.0 / model.J3[wheel_bars[model.torque_wheels]], rig.side_axis, rig.side_sign]
        parts += [[RCOND]]
        return np.concatenate([np.asarray(p, float).ravel() for p in parts])

    @staticmethod
    def _sizes(model):
        """The kernel's sizes and index arrays (``rig_layout`` in C)."""
        rig = model.rig
        n_tq = len(model.torque_wheels)
        react = rig.reaction_slots if rig.reaction else np.full(n_tq, -1)
        head = [model.m, model.beta, model.alpha, len(model.wheel_bars), n_tq, len(rig.bars)]
        parts = [head + [len(rig.hinges)], model.wheel_bars, model.torque_wheels, rig.bars]
        parts += [rig.side_bar, rig.side_slot, react]
        return np.concatenate([np.asarray(p, np.int64).ravel() for p in parts])

    def rhs(self, t, x, u):
        """dx/dt, shape (layout.size,), of the state ``x`` under input ``u`` (the layout of
        :meth:`RigFidelity.rhs`)."""
        if self.kernel is None:  # pragma: no cover - depends on the build
            return self.model.rig.rhs(t, x, u)
        out = np.empty(self.state_size)
        x, u = (np.ascontiguousarray(a, float) for a in (x, u))
        self.kernel.rig_rhs(self._consts, self._dims, x, u, out, self._work)
        return out
