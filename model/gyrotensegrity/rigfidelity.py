"""The rig-fidelity option: hinge joints, stator axial inertia and the motor's reaction torque.

The paper's bars are lines joined by ball joints; a torque about a bar's axis has nowhere to go,
so a motor's reaction torque is dropped (docs/model.md). On the rig the stators sit on the bars
and the joints are hinges. With a scene's ``[rig_fidelity]`` table (docs/rig-fidelity.md) the
model keeps the paper's node coordinates ``eta2`` (Eq. 63, ball joints eliminated exactly) and
adds, for each bar that needs it, only its rotation about its own axis:

- ``omega_ax`` (rad/s): the bar's angular velocity about ``b_hat``, with axial inertia ``J_s``
  (the stator's);
- ``e`` (3,): a unit vector fixed in the bar, normal to it, which tracks the bar's roll:
  ``e_dot = -b_hat (b_hat_dot . e) + omega_ax b_hat x e``.

The bar's angular velocity is ``w = b x b_dot / |b|^2 + omega_ax b_hat``. A hinge at a node of
bars i and j holds an axis ``h`` fixed in both (``h_i = h_j``, ``h_p`` given in bar p's frame
``b_hat, e, b_hat x e``): velocity constraint ``w_i x h_i - w_j x h_j = 0``, whose multipliers
are the hinge's torques about the two axes normal to ``h``. Bar lengths are constraints too
(their multipliers are the paper's lambda). With generalized speeds ``v = [vec(eta2_dot),
omega_ax]`` the accelerations solve ``M a = Q + G^T mu``, ``G a = -gamma`` with the constant
``M = diag(kron(I3, U2^T M_s U2), J_s)`` (Eq. 68); a closed loop of hinges has redundant rows,
so ``mu`` is the least-squares solution (the accelerations are unique).

Forces ``Q``: the paper's strings and external forces; the gyroscopic couple of each bar with
its whole axial momentum ``H_ax = J_3 omega_w + J_s omega_ax`` (Eq. 34 with ``H_ax`` for
``J_a l^2 omega_w``); the motor torque ``-tau`` on the stator's bar (``motor_reaction``). The
rotor keeps Eq. 55 (``J_3 omega_w_dot = tau``, ``omega_w`` its absolute spin).

State appended to the paper's (``model.layout.rig``): ``[omega_ax (k) | vec(e) (3k), row by
row]`` for the ``k`` bars in :attr:`RigFidelity.bars`.
"""

import numpy as np

from . import diagnostics
from .dynamics import right, string_force_densities
from .errors import SceneError

RCOND = 1e-9  # relative singular-value cut of the multiplier solve: exact redundancies only
PARALLEL = 1e-9  # |b_i x b_j| / (l_i l_j) below which two bars at a hinge count as collinear


def rig_fidelity(model):
    """The rig-fidelity terms of ``model`` (a :class:`RigFidelity`), or None when the scene's
    option adds nothing (no option, or ball joints, no stator inertia and no motor reaction):
    then the model is the paper's, unchanged."""
    spec = model.scene.rig
    if spec is None or (
        spec.joints == "ball" and spec.stator_inertia == 0.0 and not spec.motor_reaction
    ):
        return None
    return RigFidelity(model)


class RigFidelity:
    """Hinges, bar axial states and motor reactions of a compiled model (see the module doc).

    Attributes
    ----------
    bars : ndarray of int, shape (k,)
        The bars with an axial state (at a hinge or carrying a stator).
    J_s : ndarray, shape (k,), kg m^2
    hinges : list of (str, int, int, ndarray (3,), ndarray (3,))
        Node name, bars i and j, and the hinge axis in the frames of bars i and j
        (coefficients of ``b_hat``, ``e``, ``b_hat x e``).
    e0 : ndarray, shape (3, k)
        Initial roll vectors.
    """

    def __init__(self, model):
        self.model = model
        spec, scene = model.scene.rig, model.scene
        N0 = model.structure.N0
        B0 = N0[:, model.structure.bar_end] - N0[:, model.structure.bar_start]
        axes = self._hinge_axes(scene, B0) if spec.joints == "hinge" else []
        axial = {p for _, i, j, _ in axes for p in (i, j)}
        if spec.stator_inertia > 0.0 or spec.motor_reaction:
            axial |= {int(i) for i in model.wheel_bars}
        self.bars = np.array(sorted(axial), dtype=int)
        self._check(spec, scene, model)
        self.J_s = np.full(len(self.bars), spec.stator_inertia)
        self.slot = {int(i): k for k, i in enumerate(self.bars)}
        self.e0 = np.column_stack([_normal_to(B0[:, i]) for i in self.bars])
        self.hinges = [
            (name, i, j, self._in_frame(h, B0, i), self._in_frame(h, B0, j))
            for name, i, j, h in axes
        ]
        sides = [(i, hi, 1.0) for _, i, _, hi, _ in self.hinges]
        sides += [(j, hj, -1.0) for _, _, j, _, hj in self.hinges]
        self.side_bar = np.array([q for q, _, _ in sides], dtype=int)
        self.side_slot = np.array([self.slot[q] for q, _, _ in sides], dtype=int)
        self.side_axis = np.array([c for _, c, _ in sides]).reshape(-1, 3).T
        self.side_sign = np.array([sg for _, _, sg in sides])
        tq_bars = model.wheel_bars[model.torque_wheels]
        self.reaction = spec.motor_reaction
        self.reaction_slots = np.array([self.slot[int(i)] for i in tq_bars], dtype=int)
        self.E_bar = model.E.toarray()  # (beta, m): b_i = eta2 E[i]^T + const
        self.size = 4 * len(self.bars)

    # -- compile --------------------------------------------------------------------------------
    @staticmethod
    def _hinge_axes(scene, B0):
        """(node, bar i, bar j, axis) of every node joining two bars; the axis is the normal of
        the two bars at t = 0."""
        out = []
        for name in scene.node_names:
            bars = [i for i, b in enumerate(scene.bars) if name in (b.start, b.end)]
            if len(bars) < 2:
                continue
            if len(bars) > 2:
                raise SceneError(
                    f"{scene.source}: rig_fidelity.joints: node {name} joins {len(bars)} bars; "
                    "a hinge joins two"
                )
            i, j = bars
            h = np.cross(B0[:, i], B0[:, j])
            norm = np.linalg.norm(h)
            if norm <= PARALLEL * np.linalg.norm(B0[:, i]) * np.linalg.norm(B0[:, j]):
                raise SceneError(
                    f"{scene.source}: rig_fidelity.joints: bars {scene.bars[i].name} and "
                    f"{scene.bars[j].name} are collinear at node {name}: no hinge axis"
                )
            out.append((name, i, j, h / norm))
        return out

    def _check(self, spec, scene, model):
        wheel_bars = {int(i) for i in model.wheel_bars}
        for i in self.bars:
            if i not in wheel_bars:
                raise SceneError(
                    f"{scene.source}: rig_fidelity.joints: bar {scene.bars[i].name} is at a "
                    "hinge but carries no stator (no wheel): its axial inertia is not given"
                )
        if len(self.bars) and spec.stator_inertia <= 0.0:
            raise SceneError(
                f"{scene.source}: rig_fidelity.stator_inertia: must be positive with hinge "
                "joints or motor_reaction (the bars' rotation about their axes needs inertia)"
            )
        if spec.motor_reaction and len(model.speed_wheels):
            i = model.wheel_bars[model.speed_wheels[0]]
            raise SceneError(
                f"{scene.source}: rig_fidelity.motor_reaction: the wheel of bar "
                f"{scene.bars[i].name} is speed-controlled; the reaction needs its motor torque "
                "(give the wheel a number spin and a torque)"
            )

    def _in_frame(self, h, B0, i):
        b_hat = B0[:, i] / np.linalg.norm(B0[:, i])
        e = self.e0[:, self.slot[i]]
        return np.array([h @ b_hat, h @ e, h @ np.cross(b_hat, e)])

    # -- state --------------------------------------------------------------------------------
    def split(self, x):
        """``omega_ax`` (k,) rad/s and ``e`` (3, k) of a state."""
        r = x[self.model.layout.rig]
        k = len(self.bars)
        return r[:k], r[k:].reshape(3, k)

    def initial(self):
        """The appended initial state: no axial spin, the initial roll vectors."""
        return np.concatenate([np.zeros(len(self.bars)), self.e0.ravel()])

    def project_velocities(self, x):
        """Return x with ``[eta2_dot, omega_ax]`` moved (min-norm) onto the bar-length and hinge
        velocity constraints."""
        m, L = self.model, self.model.layout
        N, N_dot = m.nodes(x)
        w_ax, e = self.split(x)
        B, B_dot = _bars(m, N), _bars(m, N_dot)
        G, _ = self.constraints(B, B_dot, w_ax, e)
        v = np.concatenate([x[L.q_dot], w_ax])
        v = v - np.linalg.pinv(G, rcond=RCOND) @ (G @ v)
        x = x.copy()
        x[L.q_dot] = v[: 3 * m.m]
        x[L.rig][: len(self.bars)] = v[3 * m.m :]
        return x

    # -- dynamics -------------------------------------------------------------------------------
    def axial_momentum(self, omega_w, w_ax):
        """H_ax (beta,) kg m^2/s: rotor spin plus the bar's own axial spin."""
        m = self.model
        H = np.zeros(m.beta)
        H[m.wheel_bars] = m.J3[m.wheel_bars] * omega_w
        H[self.bars] += self.J_s * w_ax
        return H

    def constraints(self, B, B_dot, w_ax, e):
        """Velocity Jacobian ``G`` (r, 3m + k) and ``gamma`` (r,) with ``G a + gamma`` the
        constraints' second derivative: bar lengths (``b . b_dot``), then 3 rows per hinge."""
        m, Eb = self.model, self.E_bar
        k, mm, nh = len(self.bars), self.model.m, len(self.hinges)
        G = np.zeros((m.beta + 3 * nh, 3 * mm + k))
        G[: m.beta, : 3 * mm] = (B.T[:, :, None] * Eb[:, None, :]).reshape(m.beta, 3 * mm)
        gamma = np.zeros(G.shape[0])
        gamma[: m.beta] = np.sum(B_dot**2, axis=0)
        if not nh:
            return G, gamma
        # both sides of every hinge at once: columns [bars i of all hinges | bars j]
        p, s, coef, sign = self.side_bar, self.side_slot, self.side_axis, self.side_sign
        b, bd = B[:, p], B_dot[:, p]
        l2 = np.sum(b * b, axis=0)
        b_hat, b_hat_dot = _unit_and_rate(b, bd)
        h = coef[0] * b_hat + coef[1] * e[:, s] + coef[2] * _cross(b_hat, e[:, s])
        # b_ddot -> (b x b_ddot) x h / |b|^2 = ((h . b) I - b h^T) b_ddot / |b|^2
        A = np.sum(h * b, axis=0)[:, None, None] * np.eye(3) - np.einsum("ip,jp->pij", b, h)
        A = A * (sign / l2)[:, None, None]
        blocks = (A[:, :, :, None] * Eb[p][:, None, None, :]).reshape(2 * nh, 3, 3 * mm)
        Gh = np.zeros((nh, 3, 3 * mm + k))
        Gh[:, :, : 3 * mm] = blocks[:nh] + blocks[nh:]
        axial = sign * _cross(b_hat, h)
        rows = np.arange(nh)
        Gh[rows, :, 3 * mm + s[:nh]] += axial[:, :nh].T
        Gh[rows, :, 3 * mm + s[nh:]] += axial[:, nh:].T
        G[m.beta :] = Gh.reshape(3 * nh, -1)
        w = _cross(b, bd) / l2 + w_ax[s] * b_hat
        w_dot0 = -2.0 * np.sum(b * bd, axis=0) * _cross(b, bd) / l2**2 + w_ax[s] * b_hat_dot
        g = sign * (_cross(w_dot0, h) + _cross(w, _cross(w, h)))
        gamma[m.beta :] = (g[:, :nh] + g[:, nh:]).T.ravel()
        return G, gamma

    def _solve_mass(self, V):
        """M^-1 V for V (3m + k, r)."""
        m, mm = self.model, self.model.m
        r = V.shape[1]
        Ve = V[: 3 * mm].reshape(3, mm, r).transpose(1, 0, 2).reshape(mm, 3 * r)
        Xe = m.M_red_lu.solve(Ve).reshape(mm, 3, r).transpose(1, 0, 2).reshape(3 * mm, r)
        return np.vstack([Xe, V[3 * mm :] / self.J_s[:, None]])

    def rhs(self, t, x, u):
        """dx/dt of the rig-fidelity model (same layout as the paper's plus ``layout.rig``)."""
        m, st, L = self.model, self.model.structure, self.model.layout
        N, N_dot = m.nodes(x)
        B, B_dot = _bars(m, N), _bars(m, N_dot)
        w_ax, e = self.split(x)
        omega_w = m.wheel_speeds(x, u)

        S = N[:, st.string_end] - N[:, st.string_start]
        S_dot = N_dot[:, st.string_end] - N_dot[:, st.string_start]
        gamma_s = string_force_densities(m, S, S_dot, u[: m.alpha])
        F = m.W - right(m.C_s_T, S * gamma_s)
        H_ax = self.axial_momentum(omega_w, w_ax)
        F = F + right(m.C_b_T, _cross(B, B_dot) * (H_ax / m.l**3))
        tau_ax = np.zeros(len(self.bars))
        torque = u[m.alpha + m.torque_wheels]
        if self.reaction:
            np.subtract.at(tau_ax, self.reaction_slots, torque)
        Q = np.concatenate([np.asarray(m.U2.T @ F.T).T.ravel(), tau_ax])

        G, gamma = self.constraints(B, B_dot, w_ax, e)
        MQ = self._solve_mass(Q[:, None])[:, 0]
        MG = self._solve_mass(G.T)
        mu = np.linalg.lstsq(G @ MG, -gamma - G @ MQ, rcond=RCOND)[0]
        a = MQ + MG @ mu

        b_hat, b_hat_dot = _unit_and_rate(B[:, self.bars], B_dot[:, self.bars])
        e_dot = -b_hat * np.sum(b_hat_dot * e, axis=0) + w_ax * _cross(b_hat, e)
        omega_dot = torque / m.J3[m.wheel_bars[m.torque_wheels]]
        return np.concatenate(
            [x[L.q_dot], a[: 3 * m.m], omega_w, omega_dot, a[3 * m.m :], e_dot.ravel()]
        )

    def angular_momentum(self, x, u):
        """Total angular momentum about the origin (3,), kg m^2/s: the paper's bodies and rotors
        plus the bars' axial spin ``J_s omega_ax b_hat``."""
        m = self.model
        N, N_dot = m.nodes(x)
        w_ax, _ = self.split(x)
        B = _bars(m, N)[:, self.bars]
        H = diagnostics.angular_momentum(m, N, N_dot, m.wheel_speeds(x, u))
        return H + np.sum(self.J_s * w_ax * B / m.l[self.bars], axis=1)


def _bars(model, N):
    st = model.structure
    return N[:, st.bar_end] - N[:, st.bar_start]


def _cross(a, b):
    """Column-wise cross product of (3, k) arrays (np.cross costs more at these sizes)."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def _unit_and_rate(B, B_dot):
    """b_hat and its rate d/dt (b / |b|) of bar vectors (3,) or (3, k)."""
    length = np.linalg.norm(B, axis=0)
    b_hat = B / length
    return b_hat, (B_dot - b_hat * np.sum(b_hat * B_dot, axis=0)) / length


def _normal_to(b):
    """A unit vector normal to b (from the coordinate axis least aligned with it)."""
    b_hat = b / np.linalg.norm(b)
    a = np.eye(3)[int(np.argmin(np.abs(b_hat)))]
    n = a - (a @ b_hat) * b_hat
    return n / np.linalg.norm(n)
