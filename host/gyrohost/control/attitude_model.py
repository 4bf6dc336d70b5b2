"""The attitude of any scene at a frozen shape, from its angular momentum: the first piece of a
three-axis planner (no command uses it yet).

Held rigid at a shape ``N`` (m), a free structure's angular momentum about its centre of mass is
``H = I w + h omega_w`` (world axes): ``I`` (3, 3) kg m^2 its locked inertia tensor, ``w`` its
angular velocity, ``h`` (3, n_w) kg m^2 each wheel's momentum per rad/s of spin, ``omega_w``
the spins. Nothing outside acts on it (no gravity, no fixed node, no external force), so ``H``
is constant, and a change of wheel speed turns the body the other way.

In the body frame's axes (the scene's ``[attitude]`` frame, :class:`gyrotensegrity.BodyFrame`)
``I_b`` and ``h_b`` of a rigid shape are constant. With ``A`` the frame's attitude (its rotation
from its start, quaternion ``q``) and ``H_0`` the momentum in the start frame's axes::

    w_b = I_b^-1 (A^T H_0 - h_b omega_w),     q_dot = q * (0, w_b) / 2,     omega_w_dot = u

:func:`rhs` is that right-hand side in the model's convention ``f(t, x, u, params)``, state
``x = [q (4) | omega_w (n_w)]``, input ``u = omega_w_dot`` (n_w,) rad/s^2, written with
arithmetic only, so a complex step through it gives exact derivatives. Strings that change the
shape are not in it: ``I_b`` and ``h_b`` would then follow the rest lengths.
"""

from dataclasses import dataclass

import numpy as np

from gyrotensegrity import BodyFrame, diagnostics

from .errors import PlanError


@dataclass(frozen=True)
class MomentumParams:
    """The constants of :func:`rhs`, body-frame axes.

    Attributes
    ----------
    H0 : ndarray, shape (3,), kg m^2/s
        Total angular momentum about the centre of mass, the start frame's axes.
    I_b : ndarray, shape (3, 3), kg m^2
        Locked inertia tensor about the centre of mass.
    h_b : ndarray, shape (3, n_w), kg m^2
        Each wheel's angular momentum per rad/s of its spin.
    """

    H0: np.ndarray
    I_b: np.ndarray
    h_b: np.ndarray


def centre_of_mass(model, N):
    """Centre of mass, m, shape (3,), of the model at node positions ``N`` (3, n) m: each bar
    (with its wheel) at its middle, each point mass at its node."""
    st = model.structure
    centres = 0.5 * (N[:, st.bar_start] + N[:, st.bar_end])
    weighted = centres @ model.m_t + N @ model.m_node
    return weighted / (np.sum(model.m_t) + np.sum(model.m_node))


def momentum_map(model, N):
    """``(I, h)`` of the shape ``N`` (3, n) m held rigid, world axes about its centre of mass:
    the locked inertia tensor (3, 3) kg m^2 (column k: the momentum of a unit rotation about
    axis k) and the wheels' momentum per rad/s (3, n_w) kg m^2."""
    N = np.asarray(N, float)
    arm = N - centre_of_mass(model, N)[:, None]
    n_w = len(model.wheel_bars)
    inertia = [
        diagnostics.angular_momentum(model, N, np.cross(e, arm.T).T, np.zeros(n_w))
        for e in np.eye(3)
    ]
    wheels = [diagnostics.angular_momentum(model, N, np.zeros_like(N), e) for e in np.eye(n_w)]
    return np.column_stack(inertia), np.column_stack(wheels) if n_w else np.zeros((3, 0))


def check_free(model) -> None:
    """Raise :class:`PlanError` unless nothing outside acts on ``model``'s scene (its angular
    momentum is then constant)."""
    scene = model.scene
    acting = [
        what
        for what, present in (
            ("fixed nodes", bool(scene.fixed)),
            ("gravity", bool(np.any(scene.gravity))),
            ("external forces", bool(scene.forces)),
        )
        if present
    ]
    if acting:
        raise PlanError(
            f"scene {scene.name}: its angular momentum is not conserved ({', '.join(acting)})"
        )


def params_at(model, x, u=None) -> MomentumParams:
    """:class:`MomentumParams` of the model's state ``x`` (its shape frozen as it is; ``u`` the
    input, for speed-controlled wheels' spins, default the scene's at 0), in the axes of the
    scene's body frame: its start frame for ``H0``, the frame at ``x`` for ``I_b`` and
    ``h_b``."""
    check_free(model)
    frame = BodyFrame.of_model(model)
    N, N_dot = model.nodes(x)
    omega_w = model.wheel_speeds(x, model.input_at(0.0) if u is None else u)
    centre, velocity = centre_of_mass(model, N), centre_of_mass(model, N_dot)
    H = diagnostics.angular_momentum(model, N - centre[:, None], N_dot - velocity[:, None], omega_w)
    I_w, h_w = momentum_map(model, N)
    F = frame.F0 @ frame.rotation(N)  # the frame at x, world axes
    return MomentumParams(frame.F0.T @ H, F.T @ I_w @ F, F.T @ h_w)


def quaternion_product(p, q):
    """Hamilton product ``p q`` of quaternions (w, x, y, z), shape (4,) (complex-step safe)."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ]
    )


def rotation_of(q):
    """Rotation matrix (3, 3) of a unit quaternion (w, x, y, z) (complex-step safe)."""
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def body_rate(x, params: MomentumParams):
    """Angular velocity, rad/s, body axes, shape (3,), of the state ``x = [q | omega_w]``."""
    q, omega_w = x[:4], x[4:]
    H_b = rotation_of(q).T @ params.H0
    return np.linalg.solve(params.I_b, H_b - params.h_b @ omega_w)


def rhs(t, x, u, params: MomentumParams):
    """``dx/dt`` of ``x = [q (4) | omega_w (n_w)]`` under wheel accelerations ``u`` (n_w,)
    rad/s^2 (the module's equations; ``t`` unused: nothing depends on time)."""
    w_b = body_rate(x, params)
    q_dot = 0.5 * quaternion_product(x[:4], np.concatenate([[0.0], w_b]))
    return np.concatenate([q_dot, np.asarray(u)])
