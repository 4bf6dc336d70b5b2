"""The wheels' motor reaction in the filter's process model: a turn of the whole structure.

A wheel's motor speeds its rotor up about its bar's axis and pushes back on the bar with the
torque ``-J_3 omega_w_dot b_hat``. The paper's bars are lines that carry no torque about their
own axis, so its model drops that reaction. On a rig whose bars meet at hinges (the D-bar rig;
a truth scene with ``[rig_fidelity] motor_reaction`` on hinged joints) the hinges pass it to
the neighbouring bars and the whole structure turns the other way: the total angular momentum,
the wheels' spin included, is kept. This is the "body" coupling of
:mod:`gyrohost.control.wheel_reaction`, which the attitude planner's momentum balance assumes.

The filter adds that turn to the model's accelerations as the rigid motion the torque starts.
With ``I`` the structure's locked inertia about its centre of mass ``c`` (from the model's own
mass matrix, as the planner's balance) and ``tau`` the wheels' summed reaction::

    alpha = I^-1 tau,        N_ddot += alpha x (N - c)

A rigid motion from rest keeps every bar's length (``b . (alpha x b) = 0``), so adding it to the
constrained accelerations is the model's exact response to the generalised forces ``M a`` whose
moment about ``c`` is ``tau`` and whose sum is zero. How the hinges spread the torque along the
structure, which would also bend it a little, is left out.

Written with arithmetic only (complex-step safe): :meth:`MotorReaction.jacobian` takes its
derivatives by the complex step, over the node coordinates and the wheel spins it depends on.
"""

import numpy as np

from . import complex_step
from .errors import EstimatorConfigError


class MotorReaction:
    """The reaction's reduced accelerations for a free structure with hinged wheel bars.

    Parameters
    ----------
    dyn : gyrotensegrity.fast.FastDynamics
        The filter's dynamics (reduced coordinates ``z``, nodes ``N = N_fix + z U^T``).

    Raises
    ------
    EstimatorConfigError
        A node is fixed (its mount takes the reaction: nothing turns), or a wheel sits on a bar
        that meets no other bar (nothing passes the reaction on).
    """

    def __init__(self, dyn):
        model = dyn.model
        name = model.scene.name
        UT = np.asarray(dyn.U_T.A)  # (m', n): N = N_fix + z UT
        ones = np.ones(UT.shape[1])
        # the reduced coordinates of a unit translation (t UT = 1: every node moves alike)
        translation = np.linalg.lstsq(UT.T, ones, rcond=None)[0]
        held = np.any(np.asarray(dyn.N_fix) != 0.0)
        if held or not np.allclose(translation @ UT, ones, rtol=0.0, atol=1e-9):
            raise EstimatorConfigError(
                f"estimator key 'wheel_reaction' = 'body' on scene {name!r}: the scene holds "
                "nodes, whose mount takes the wheels' reaction; it turns only a free structure"
            )
        jointed = model.scene.jointed_bars()
        loose = [model.scene.bars[i].name for i in dyn.wheel_bars if i not in jointed]
        if loose:
            raise EstimatorConfigError(
                f"estimator key 'wheel_reaction' = 'body' on scene {name!r}: the wheel bar(s) "
                f"{', '.join(loose)} meet no other bar, so no hinge passes their reaction on"
            )
        self.dyn, self.translation = dyn, translation
        M_s = model.M_s.toarray()
        self.M_z = UT @ M_s @ UT.T
        self.centre_weights = UT @ M_s @ ones / (ones @ M_s @ ones)  # c = z w
        self.J3 = model.J3[dyn.wheel_bars]

    def accelerations(self, q, omega_dot):
        """Reduced accelerations (K, 3, m') m/s^2 of the reaction at coordinates ``q`` (K, 3,
        m') m with the spins changing at ``omega_dot`` (K, n_w) rad/s^2 (real or complex)."""
        dyn = self.dyn
        B = (dyn.EE_T(q) + dyn.off)[..., dyn.wheel_bars]  # (K, 3, n_w), spin axes +b
        length = np.sqrt((B * B).sum(axis=-2))
        tau = -((self.J3 * omega_dot / length)[..., None, :] * B).sum(axis=-1)  # (K, 3)
        R = q - (q @ self.centre_weights)[..., None] * self.translation
        J = R @ self.M_z @ np.swapaxes(R, -1, -2)  # second moment (K, 3, 3)
        trace = J[..., 0, 0] + J[..., 1, 1] + J[..., 2, 2]
        inertia = trace[..., None, None] * np.eye(3) - J
        alpha = np.linalg.solve(inertia, tau[..., None])[..., 0]
        return np.cross(alpha[..., None, :], np.swapaxes(R, -1, -2)).swapaxes(-1, -2)

    def jacobian(self, x, layout, spin_rates):
        """Derivatives (3 m', n_dynamic) of the reaction's accelerations with respect to the
        dynamic state ``x``, by the complex step over the node coordinates and the wheel spins.

        ``spin_rates(omega)`` gives the spins' rates (K, n_w) rad/s^2 of spins (K, n_w) (the
        process model's wheel law, complex-safe)."""
        L = layout
        columns = np.r_[np.arange(L.q.start, L.q.stop), np.arange(L.omega.start, L.omega.stop)]
        X = complex_step.perturbed(x[: L.n_dynamic], columns)
        a = self.accelerations(X[:, L.q].reshape(len(X), 3, L.m), spin_rates(X[:, L.omega]))
        value, slopes = complex_step.split(a.reshape(len(X), -1))
        out = np.zeros((3 * L.m, L.n_dynamic))
        out[:, columns] = slopes
        return value, out
