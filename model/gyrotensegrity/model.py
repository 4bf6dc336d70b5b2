"""The compiled model: constant matrices of a scene, state layout and inputs.

``Model(scene)`` does all the work that does not depend on the state (the "compiled model"):
connectivity, the mass matrix ``M_s`` (Eq. 56) and its inverse, the SVD of ``P`` (Eq. 63),
the reduced mass matrix ``U2^T M_s U2`` (Eq. 68) factorized once, the constant parts of the
Lagrange-multiplier system (Eq. 67) and the constant external forces ``W``. The per-evaluation
work lives in :mod:`gyrotensegrity.dynamics`. See ``docs/model.md`` for the equations-to-code map.

State ``x`` (flat, float64)::

    x = [ vec(eta2) (3 m) | vec(eta2_dot) (3 m) | theta_w (n_w) | omega_w of torque wheels (n_tq) ]

``eta2`` is the (3, m) matrix of independent coordinates (Eq. 63), flattened row by row (all x,
then all y, then all z); with no constraints ``eta2 = N``. ``theta_w`` are the wheel angles
(rad) of all wheels; the spin of a torque-driven wheel is a state, the spin of a
speed-controlled wheel is an input.

Input ``u`` (flat)::

    u = [ rest lengths of the strings (alpha), m | wheel inputs (n_w) ]

where a wheel input is the commanded spin (rad/s) of a speed-controlled wheel or the motor
torque (N m, about +b) of a torque-driven wheel.
"""

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .errors import PrunedTermError
from .scene import Scene
from .structure import Structure, compile_structure

ANCHOR_MASS = 1.0  # kg; nominal mass of a fixed string-only node (eliminated, see docs/model.md)


@dataclass(frozen=True)
class StateLayout:
    """Sizes and slices of the flat state vector."""

    m: int
    n_wheels: int
    n_torque: int
    n_rig: int = 0  # states of the rig-fidelity option (docs/rig-fidelity.md)

    @property
    def size(self) -> int:
        return 6 * self.m + self.n_wheels + self.n_torque + self.n_rig

    @property
    def q(self) -> slice:
        return slice(0, 3 * self.m)

    @property
    def q_dot(self) -> slice:
        return slice(3 * self.m, 6 * self.m)

    @property
    def theta(self) -> slice:
        return slice(6 * self.m, 6 * self.m + self.n_wheels)

    @property
    def omega(self) -> slice:
        return slice(6 * self.m + self.n_wheels, self.size - self.n_rig)

    @property
    def rig(self) -> slice:
        return slice(self.size - self.n_rig, self.size)


class Model:
    """Compiled gyroscopic tensegrity model of a scene.

    A term is left out only when nothing can make it act: not the scene, not its inputs, not
    a controller, an initial state or :meth:`Stepper.step <gyrotensegrity.Stepper.step>`
    inputs. Every wheel has an input (speed or torque), so the gyroscopic term is built for
    every scene with wheels, whatever their initial spin and schedules. ``omit`` leaves it
    out on the caller's word; then every evaluation whose wheels spin or are driven raises
    :class:`~gyrotensegrity.errors.PrunedTermError` instead of dropping the term.

    Parameters
    ----------
    scene : Scene
    omit : iterable of str, optional
        Terms the caller declares unused (only ``"gyroscopic"``: wheels that never spin).

    Raises
    ------
    ValueError
        An ``omit`` entry is not an omittable term.
    PrunedTermError
        The scene itself spins or drives a wheel while ``"gyroscopic"`` is omitted.

    Attributes
    ----------
    structure : Structure
    terms : frozenset of str
        The model terms built for this scene (see :data:`ALL_TERMS`).
    omitted : frozenset of str
        The terms left out on the caller's word (``omit``).
    layout : StateLayout
    l, m_t, J_t, J_a : ndarray, shape (beta,)
        Bar lengths (m), bar + wheel masses (kg), J_t and J_a (kg, Eq. 16).
    m_node : ndarray, shape (n,), kg
        Point masses of string-to-string nodes (0 elsewhere).
    W : ndarray, shape (3, n), N
        Constant external node forces (gravity and the scene's forces).
    rig : RigFidelity or None
        The scene's rig-fidelity terms (:mod:`gyrotensegrity.rigfidelity`); None: the paper's.
    """

    ALL_TERMS = (
        "gyroscopic",  # wheels: J_a terms in W_T (Eq. 59) and the spin equation (Eq. 55)
        "wheel_torque",  # torque-driven wheels: spin in the state
        "multipliers",  # class-k joints or fixed nodes: Omega (Eq. 67), reduced order (Eq. 68)
        "point_masses",  # string-to-string nodes (Eq. 42)
        "gravity",
        "external_forces",
        "string_damping",
    )
    OMITTABLE = ("gyroscopic",)

    def __init__(self, scene: Scene, omit=()):
        self.scene = scene
        st = self.structure = compile_structure(scene)
        self.n, self.beta, self.alpha, self.c = st.n, len(scene.bars), len(scene.strings), st.c
        # transposes for the products X C_b, X C_s, X P of dense (3, k) matrices X
        self.C_b_T, self.C_s_T, self.P_T = st.C_b.T.tocsr(), st.C_s.T.tocsr(), st.P.T.tocsr()
        self._bar_constants(scene)
        self._wheels(scene)
        self._strings(scene)
        self._mass_matrix(scene, st)
        self._reduced_coordinates(st)
        self._external_forces(scene, st)
        if self.c:
            self._multiplier_system(st)
        self.omitted = self._omitted(omit)
        self.terms = frozenset(self._which_terms(scene)) - self.omitted
        from .rigfidelity import rig_fidelity  # imports the dynamics, which import this module

        self.rig = rig_fidelity(self)  # None: the paper's model
        n_rig = self.rig.size if self.rig else 0
        self.layout = StateLayout(self.m, len(self.wheel_bars), len(self.torque_wheels), n_rig)
        if self.omitted:  # the scene's own spins and schedules
            self.check_omitted(self.spin0[self.torque_wheels], np.zeros(len(self.wheel_bars)))
            for k, schedule in enumerate(self.wheel_schedules):
                peak = schedule.value[np.argmax(np.abs(schedule.value))]
                self._check_wheel(k, peak, "has a scheduled input of", self._unit(k))

    # -- compile steps --------------------------------------------------------------------------
    def _bar_constants(self, scene):
        st = self.structure
        B0 = st.N0[:, st.bar_end] - st.N0[:, st.bar_start]
        self.l = np.linalg.norm(B0, axis=0)
        self.m_b = np.array([b.mass for b in scene.bars])
        w = [b.wheel for b in scene.bars]
        self.m_w = np.array([0.0 if x is None else x.mass for x in w])
        r = np.array([0.0 if x is None else x.radius for x in w])
        lw = np.array([0.0 if x is None else x.thickness for x in w])
        # a scene's identified inertias override the disc's and the uniform bar's formulas
        J1 = self.m_w * (3.0 * r**2 + lw**2) / 12.0  # Eq. 12
        J3 = 0.5 * self.m_w * r**2
        self.J1 = np.array(
            [J if x is None or x.J1 is None else x.J1 for J, x in zip(J1, w, strict=True)]
        )
        self.J3 = np.array(
            [J if x is None or x.J3 is None else x.J3 for J, x in zip(J3, w, strict=True)]
        )
        bars = zip(scene.bars, self.l, strict=True)
        I_b = np.array([b.mass / 12.0 if b.inertia is None else b.inertia / L**2 for b, L in bars])
        self.J_t = I_b + self.J1 / self.l**2  # Eq. 16
        self.J_a = self.J3 / self.l**2
        self.m_t = self.m_b + self.m_w

    def _wheels(self, scene):
        self.wheel_bars = np.array([i for i, b in enumerate(scene.bars) if b.wheel], dtype=int)
        wheels = [scene.bars[i].wheel for i in self.wheel_bars]
        self.wheel_modes = [w.mode for w in wheels]
        self.torque_wheels = np.array(
            [k for k, w in enumerate(wheels) if w.mode == "torque"], dtype=int
        )
        self.speed_wheels = np.array(
            [k for k, w in enumerate(wheels) if w.mode == "speed"], dtype=int
        )
        self.wheel_schedules = [w.speed if w.mode == "speed" else w.torque for w in wheels]
        self.spin0 = np.array([w.spin0 for w in wheels])

    def _strings(self, scene):
        self.k_s = np.array([s.stiffness for s in scene.strings])
        self.c_s = np.array([s.damping for s in scene.strings])
        self.rest_schedules = [s.rest_length for s in scene.strings]

    def _mass_matrix(self, scene, st: Structure):
        """M_s (Eq. 56) and its inverse via Eq. 47:
        M_s^-1 = 1/4 C_b^T J_t^-1 C_b + 4 C_r^T m_t^-1 C_r (+ point masses)."""
        self.m_node = np.zeros(self.n)
        for name, mass in scene.point_masses.items():
            self.m_node[st.primary[name]] = mass
        sigma_mass = self.m_node[2 * self.beta :].copy()
        anchors = sigma_mass == 0.0  # fixed string-only nodes, eliminated by the constraints
        sigma_mass[anchors] = ANCHOR_MASS
        Jt, mt, ms = sp.diags(self.J_t), sp.diags(self.m_t), sp.diags(sigma_mass)
        C_b, C_r, C_ns = st.C_b, st.C_r, st.C_ns
        self.M_s = sp.csr_matrix(C_b.T @ Jt @ C_b + C_r.T @ mt @ C_r + C_ns.T @ ms @ C_ns)
        self.M_s_inv = sp.csr_matrix(
            0.25 * C_b.T @ sp.diags(1.0 / self.J_t) @ C_b
            + 4.0 * C_r.T @ sp.diags(1.0 / self.m_t) @ C_r
            + C_ns.T @ sp.diags(1.0 / sigma_mass) @ C_ns
        )

    def _reduced_coordinates(self, st: Structure):
        """SVD of P (Eq. 63), computed per constraint group: P is block diagonal over the groups,
        so the blocks' SVDs assemble into an SVD of P with a sparse U."""
        n, c = self.n, self.c
        U1 = sp.lil_matrix((n, c))
        V = sp.lil_matrix((c, c))
        sigma1 = np.zeros(c)
        u2_cols = []  # (rows, values) of each column of U2
        grouped = {}
        for nodes, cols in st.constraint_groups:
            grouped[nodes[0]] = (nodes, cols)
        in_group = {int(i) for nodes, _ in st.constraint_groups for i in nodes}
        for i in range(n):
            if i in grouped:
                nodes, cols = grouped[i]
                Ug, s, Vt = np.linalg.svd(st.P[nodes][:, cols].toarray())
                k = len(cols)
                for a, j in enumerate(cols):
                    U1[nodes, j] = Ug[:, a : a + 1]
                V[np.ix_(cols, cols)] = Vt.T
                sigma1[cols] = s
                u2_cols += [(nodes, Ug[:, a]) for a in range(k, len(nodes))]
            elif i not in in_group:
                u2_cols.append((np.array([i]), np.array([1.0])))
        rows = np.concatenate([r for r, _ in u2_cols]) if u2_cols else np.zeros(0, int)
        vals = np.concatenate([v for _, v in u2_cols]) if u2_cols else np.zeros(0)
        cols_idx = np.repeat(np.arange(len(u2_cols)), [len(r) for r, _ in u2_cols])
        self.m = len(u2_cols)
        self.U1, self.V, self.sigma1 = sp.csr_matrix(U1), sp.csr_matrix(V), sigma1
        self.U2 = sp.csr_matrix((vals, (rows, cols_idx)), shape=(n, self.m))
        self.eta1 = (st.D @ self.V) / sigma1 if c else np.zeros((3, 0))  # Eq. 64
        self.N_fixed_T = np.asarray(self.U1 @ self.eta1.T)  # (n, 3): the eta1 U1^T part of N
        self.M_red = sp.csc_matrix(self.U2.T @ self.M_s @ self.U2)  # Eq. 68, constant
        self.M_red_lu = spla.splu(self.M_red)
        self.E = sp.csr_matrix(st.C_b @ self.U2)  # B = eta2 E^T + const: bar rows, for projection
        self.EEt = sp.coo_matrix(self.E @ self.E.T)

    def _external_forces(self, scene, st: Structure):
        g = scene.gravity
        W = np.outer(g, self.m_t) @ st.C_r  # half of each bar-wheel weight at each end
        W = W + np.outer(g, self.m_node)
        for name, f in scene.forces.items():
            W[:, st.primary[name]] += f
        self.W = np.asarray(W)

    def _multiplier_system(self, st: Structure):
        """Constant parts of the multiplier equation (Eq. 67 post-multiplied by Sigma1 V^T):

        Omega A - 1/2 sum_i |b_i|^-2 b_i b_i^T Omega h_i q_i^T = -N_ddot_0 P, with
        A = P^T M_s^-1 P, h_i = (C_b P)[i], q_i = (C_b M_s^-1 P)[i]. In vec form (column-major,
        unknown index 3 j + r) the matrix is kron(A, I3) + sum_i kron(coef_i, b_i b_i^T / |b_i|^2),
        coef_i = -1/2 q_i h_i^T.
        """
        P = st.P
        A = sp.coo_matrix(P.T @ self.M_s_inv @ P)
        self.H = sp.csr_matrix(st.C_b @ P)
        Q = sp.csr_matrix(st.C_b @ self.M_s_inv @ P)
        r = np.arange(3)
        self.omega_const = (
            (3 * A.row[:, None] + r).ravel(),
            (3 * A.col[:, None] + r).ravel(),
            np.repeat(A.data, 3),
        )
        bars, rows, cols, coef = [], [], [], []
        for i in range(self.beta):
            for a, qa in zip(Q[i].indices, Q[i].data, strict=True):
                for b, hb in zip(self.H[i].indices, self.H[i].data, strict=True):
                    bars.append(i)
                    rows.append(a)
                    cols.append(b)
                    coef.append(-0.5 * qa * hb)
        rr, ss = np.meshgrid(r, r, indexing="ij")
        self.omega_pairs_bar = np.array(bars, dtype=int)
        self.omega_pairs_coef = np.array(coef)
        self.omega_pairs_rows = (3 * np.array(rows, dtype=int)[:, None] + rr.ravel()).ravel()
        self.omega_pairs_cols = (3 * np.array(cols, dtype=int)[:, None] + ss.ravel()).ravel()

    def _omitted(self, omit):
        omitted = frozenset(omit)
        for term in omitted - set(self.OMITTABLE):
            raise ValueError(
                f"omit: {term!r} cannot be omitted (omittable: {', '.join(self.OMITTABLE)})"
            )
        return omitted

    def _which_terms(self, scene):
        if np.any(self.J_a[self.wheel_bars] > 0.0):
            yield "gyroscopic"  # any wheel can be spun by its input (control, Stepper.step)
        if len(self.torque_wheels):
            yield "wheel_torque"
        if self.c:
            yield "multipliers"
        if np.any(self.m_node > 0.0):
            yield "point_masses"
        if np.any(scene.gravity != 0.0):
            yield "gravity"
        if scene.forces:
            yield "external_forces"
        if np.any(self.c_s > 0.0):
            yield "string_damping"

    # -- omitted terms ------------------------------------------------------------------------
    def check_omitted(self, omega_torque, wheel_input):
        """Raise when an evaluation needs an omitted term (no-op when nothing is omitted).

        Parameters
        ----------
        omega_torque : ndarray, shape (n_tq,), rad/s
            Spins of the torque-driven wheels (the state's last entries).
        wheel_input : ndarray, shape (n_w,)
            Wheel inputs: speeds (rad/s) or motor torques (N m).

        Raises
        ------
        PrunedTermError
            Naming the term and the bar of the first wheel that spins or is driven.
        """
        if "gyroscopic" not in self.omitted:
            return
        for k, value in zip(self.torque_wheels, omega_torque, strict=True):
            self._check_wheel(k, value, "spins at")
        for k, value in enumerate(wheel_input):
            self._check_wheel(k, value, "has an input of", self._unit(k))

    def _unit(self, k):
        return "rad/s" if self.wheel_modes[k] == "speed" else "N m"

    def _check_wheel(self, k, value, what, unit="rad/s"):
        if value != 0.0:
            bar = self.scene.bars[self.wheel_bars[k]].name
            raise PrunedTermError(
                f"wheel of bar {bar} {what} {float(np.real(value)):.6g} {unit}, but the model "
                "was built with omit=('gyroscopic',): build it without omit",
                "gyroscopic",
                bar,
            )

    # -- state and inputs ---------------------------------------------------------------------
    def describe(self) -> str:
        """One line saying which model was built."""
        terms = ", ".join(t for t in self.ALL_TERMS if t in self.terms) or "none"
        return (
            f"{self.beta} bars, {self.alpha} strings, {self.n} nodes, {self.c} constraints, "
            f"{self.m} independent node columns, {len(self.wheel_bars)} wheels; terms: {terms}"
        )

    def nodes(self, x):
        """Node positions and velocities of a state.

        Returns
        -------
        N, N_dot : ndarray, shape (3, n), m and m/s
        """
        L = self.layout
        q = x[L.q].reshape(3, self.m)
        q_dot = x[L.q_dot].reshape(3, self.m)
        N = (self.N_fixed_T + self.U2 @ q.T).T
        return N, np.asarray((self.U2 @ q_dot.T).T)

    def wheel_speeds(self, x, u):
        """Spin of every wheel, rad/s, shape (n_w,): from the state (torque-driven) or u (speed)."""
        omega = np.empty(len(self.wheel_bars))
        omega[self.torque_wheels] = x[self.layout.omega]
        omega[self.speed_wheels] = u[self.alpha + self.speed_wheels]
        return omega

    def state(self, N, N_dot, theta=None, omega=None):
        """The state of given node positions/velocities (they must satisfy N P = D).

        Parameters
        ----------
        N, N_dot : ndarray, shape (3, n), m and m/s
        theta : ndarray, shape (n_w,), rad, optional (default 0)
        omega : ndarray, shape (n_w,), rad/s, optional (default the scene's initial spins)
        """
        nw = len(self.wheel_bars)
        theta = np.zeros(nw) if theta is None else np.asarray(theta, float)
        omega = self.spin0 if omega is None else np.asarray(omega, float)
        self.check_omitted(omega[self.torque_wheels], np.zeros(nw))
        q = np.asarray(self.U2.T @ np.asarray(N).T).T
        q_dot = np.asarray(self.U2.T @ np.asarray(N_dot).T).T
        rig = self.rig.initial() if self.rig else []
        return np.concatenate([q.ravel(), q_dot.ravel(), theta, omega[self.torque_wheels], rig])

    def initial_state(self):
        """The scene's initial state; node velocities are projected onto the constraints
        (min-norm correction so that b_i . b_i_dot = 0 and the joints move together)."""
        from .projection import project_velocities

        st = self.structure
        x = project_velocities(self, self.state(st.N0, st.N0_dot))
        return self.rig.project_velocities(x) if self.rig else x

    def input_at(self, t: float):
        """The scene's input at time t: rest lengths (m) then wheel inputs, shape (alpha + n_w,)."""
        rest = [s(t) for s in self.rest_schedules]
        wheel = [s(t) for s in self.wheel_schedules]
        return np.array(rest + wheel, dtype=float)

    def pack_input(self, rest_length, wheel=()):
        """Build ``u`` from rest lengths (alpha,) m and wheel inputs (n_w,) (rad/s or N m)."""
        u = np.concatenate([np.asarray(rest_length, float), np.asarray(wheel, float)])
        if u.shape != (self.alpha + len(self.wheel_bars),):
            raise ValueError(
                f"input has {u.size} entries; the model takes {self.alpha} rest lengths "
                f"and {len(self.wheel_bars)} wheel inputs"
            )
        return u
