"""The truth of the simulated rig: the dynamics model of the scene, stepped with device inputs.

The scene is turned into the rig's plant (:func:`rig_scene`), its wheels at rest, because the
wheel board, not the scene, sets the spins; ``wheel_inertia_scale`` makes the truth's wheels
heavier or lighter than the scene the estimator uses (model mismatch). Two kinds of plant:

- **Speed-driven wheels** (the paper's model, and any scene without the rig-fidelity option's
  ``motor_reaction``): each wheel's spin is an input; the motor's reaction is dropped
  (docs/rig-fidelity.md), so a speed change acts on the bars only through the gyroscopic couple.
- **Torque-driven wheels** (a scene with ``[rig_fidelity] motor_reaction = true``, e.g. dbar-rig):
  each wheel's spin is in the state, driven by an ideal speed loop, the torque
  ``J_3 (omega_board(t + h) - omega) / h`` held over every step ``h``, which brings the spin to
  the board's true speed at the step's end; the reaction of that torque acts on the stator's
  bar, so every speed change of the board turns the structure by the momentum balance. The
  rig-fidelity model runs in the compiled kernel (:mod:`gyrotensegrity.fast_rig`). Such a truth
  starts **held**: its mount keeps the structure at its initial state (the reaction of the
  wheels' spin-up goes into the mount, as the experimenter's hands take it on the rig) until
  :meth:`Truth.release`; the run releases it when its lead-in starts, after the spin-up, where
  the estimator starts from the scene's initial state. :meth:`Truth.reset` holds it again.

Inputs at each step (the devices' outputs at its start and end, joined by a straight line,
:class:`gyrotensegrity.Stepper`; the servos' through every turn of their paths within it,
:meth:`Truth.step`):

- **String rest lengths.** A servo with ``string = "<name>"`` in the configuration winds that scene
  string: its present string length (the servo calibration, ``L = length_at_zero_m + length_sign *
  (p - zero_position) * 2 pi r / 4096``, :func:`gyrohost.drivers.mx12.steps_to_length`) *is* the
  string's rest length, through a first-order lag ``servo_lag_s`` (string and pulley compliance;
  0 = none). Strings no servo winds keep their scene rest length at t = 0.
- **Wheel spins.** Board wheel ``i`` spins the scene's ``i``-th wheel in bar order (rad/s, positive
  about +b of its bar); board wheels beyond the scene's wheels spin nothing. Speed-driven: the
  spin moving over the step; torque-driven: the speed loop's target at the step's end.

**Truth against model.** The truth runs ``[sim.truth] scene`` when set (:func:`truth_scene`),
the host's model, estimator and planner keep the configuration's scene: any parameter may differ
(masses, inertias, stiffness, damping, rig fidelity, node positions), the members may not (same
nodes, bars, strings and wheels, by name, joining the same nodes), so the devices map onto both.
``servo_zero_offset_rad[i]`` puts the true zero of the ``i``-th servo that far (rad of the horn,
positive towards increasing position steps) from its calibrated ``zero_position``: the truth's
string is ``length_sign * pulley_radius_m * offset`` shorter than the calibration says.

The IMU frame (body axes of :class:`~gyrohost.simrig.imu_emu.ImuTruth`) is attached to the structure
by three scene nodes ``imu_frame_nodes = [a, b, c]``: x along a -> b, z along x cross (c - a) (the
normal of the plane of a, b, c), y = z cross x; its origin, where the specific force is taken, is
the midpoint of a and b. For the D-bar (``["n1", "n3", "n2"]``) that is the centre of the rhombus,
x along n1 -> n3, z normal to the plane of the D-bar, so the frame starts aligned with the world.
The IMU's own mounting rotation (``imu.mounting_rpy_rad``, turned further by the truth's
``imu_rotation_deg``) applies on top, in the emulator.
Gravity felt by the IMU is ``imu_gravity_m_s2`` (world frame), independent of the scene's
gravity: the D-bar scenes leave gravity out because the supports cancel it, the sensor still
feels it. Sensor latency: :meth:`Truth.imu_truth` returns the truth ``imu_latency_s`` ago.
"""

import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from gyrohost.config import RigConfig, ServoConfig
from gyrohost.simrig.config import TruthConfig, truth_scene_path
from gyrohost.simrig.imu_emu import MAX_BACKLOG_S, ImuTruth
from gyrotensegrity import Model, Scene, SceneError, Stepper, load_scene
from gyrotensegrity.dynamics import string_force_densities
from gyrotensegrity.piecewise import constant
from gyrotensegrity.simulate import stable_step

from .errors import RigSetupError

FD_STEP_S = 1e-6
"""Time step of the finite difference that turns frame velocity into angular rate, s."""
MIN_PIECE_S = 1e-6
"""Shortest piece of a step through the servos' turns, s: two turns closer than this (two
servos arriving together, apart by round-off) are one, far below any motion the truth resolves,
and a piece of no length is no step."""
PIECES_PER_STEP = 32
"""Pieces of a step the IMU's history makes room for: a servo following its lag bends at
most at every tick of its emulator (one a millisecond while the rig idles, one per frame
served), rarely more than ten in a 5 ms step."""


def truth_scene(config: RigConfig, scene: str | Path | None = None) -> Scene:
    """The scene the rig's truth runs, checked against the model's scene.

    Parameters
    ----------
    config : RigConfig
        ``[sim.truth] scene`` (when set) is the truth's; ``scene`` is the model's.
    scene : str or Path, optional
        The model's scene file instead of the configuration's (and the truth's, when the
        configuration sets none).

    Raises
    ------
    RigSetupError
        A scene does not load, or the two do not have the same members (:func:`check_members`).
    """
    model_path = Path(scene) if scene is not None else config.scene_path
    truth_path = truth_scene_path(config, model_path)
    model = _load(model_path, "rig scene")
    if truth_path == model_path:
        return model
    truth = _load(truth_path, "truth scene")
    check_members(model, truth)
    return truth


def _load(path: Path, what: str) -> Scene:
    try:
        return load_scene(path)
    except (SceneError, OSError) as exc:
        raise RigSetupError(f"{what} {path}: {exc}") from exc


def check_members(model: Scene, truth: Scene) -> None:
    """Refuse a truth scene whose nodes, bars, strings or wheels are not the model's.

    Names and order must agree, and each bar and string must join the same nodes and each wheel
    sit on the same bar; parameters may differ.

    Raises
    ------
    RigSetupError
        Names the first member that differs and both scenes.
    """
    kinds = {
        "nodes": lambda sc: [(n, ()) for n in sc.node_names],
        "bars": lambda sc: [(b.name, (b.start, b.end)) for b in sc.bars],
        "strings": lambda sc: [(st.name, (st.start, st.end)) for st in sc.strings],
        "wheels": lambda sc: [(b.name, ()) for b in sc.bars if b.wheel is not None],
    }
    for kind, members in kinds.items():
        want, have = members(model), members(truth)
        for i in range(max(len(want), len(have))):
            w = want[i] if i < len(want) else None
            h = have[i] if i < len(have) else None
            if w != h:
                raise RigSetupError(
                    f"truth scene {truth.source} does not fit the model's scene {model.source}: "
                    f"{kind}[{i}] is {_member(h)} in the truth, {_member(w)} in the model "
                    f"({len(have)} {kind} against {len(want)})"
                )


def _member(member) -> str:
    if member is None:
        return "missing"
    name, nodes = member
    return f"'{name}'" + (f" on {list(nodes)}" if nodes else "")


def torque_driven(scene: Scene) -> bool:
    """Whether the rig's plant of ``scene`` drives its wheels by torque: the motor's reaction
    (``[rig_fidelity] motor_reaction``) needs the torque; otherwise they are speed-driven."""
    return scene.rig is not None and scene.rig.motor_reaction


def rig_scene(scene: Scene, wheel_inertia_scale: float = 1.0) -> Scene:
    """The plant of the rig: ``scene`` with its wheels at rest, inertia scaled, speed-driven or
    (:func:`torque_driven`) torque-driven with the torque an input.

    Parameters
    ----------
    scene : Scene
    wheel_inertia_scale : float
        Factor on the wheels' spin inertia J3 (the radius is scaled by its square root, so J3
        scales exactly and J1 nearly; masses are unchanged).
    """
    radius_scale = math.sqrt(wheel_inertia_scale)
    bars = []
    for bar in scene.bars:
        wheel = bar.wheel
        if wheel is not None:
            wheel = replace(
                wheel,
                radius=wheel.radius * radius_scale,
                J3=None if wheel.J3 is None else wheel.J3 * wheel_inertia_scale,
                J1=None if wheel.J1 is None else wheel.J1 * wheel_inertia_scale,
                mode="torque" if torque_driven(scene) else "speed",
                spin0=0.0,
                speed=None if torque_driven(scene) else constant(0.0),
                torque=constant(0.0) if torque_driven(scene) else None,
            )
        bars.append(replace(bar, wheel=wheel))
    return replace(scene, bars=bars)


@dataclass(frozen=True)
class TruthRecord:
    """The truth at every step of a recording (``k`` steps).

    Attributes
    ----------
    t_s : ndarray, shape (k,), s
    N : ndarray, shape (k, 3, n), m
        Scene node positions (primary nodes, scene node order).
    R_wb : ndarray, shape (k, 3, 3)
        Attitude of the IMU frame: its axes in the world frame.
    omega_w_rad_s : ndarray, shape (k, n_w), rad/s
        Wheel spins (scene wheel order) at the step's end.
    rest_length_m : ndarray, shape (k, alpha), m
        String rest lengths.
    node_names : list of str
    """

    t_s: np.ndarray
    N: np.ndarray
    R_wb: np.ndarray
    omega_w_rad_s: np.ndarray
    rest_length_m: np.ndarray
    node_names: list

    def save(self, path) -> None:
        """Write the arrays to a ``.npz`` file."""
        np.savez(
            path,
            t_s=self.t_s,
            N=self.N,
            R_wb=self.R_wb,
            omega_w_rad_s=self.omega_w_rad_s,
            rest_length_m=self.rest_length_m,
            node_names=np.array(self.node_names),
        )


class Truth:
    """The rig's truth model; see the module docstring.

    Parameters
    ----------
    scene : Scene
        The truth's scene (:func:`truth_scene`; the truth derives its plant from it).
    config : TruthConfig
        Step, IMU frame, gravity felt by the IMU, mismatch options.
    servos : sequence of ServoConfig
        Servos whose ``string`` names a scene string drive that string's rest length (their
        true zero off by ``config.servo_zero_offset_rad``, in this order).
    """

    def __init__(
        self, scene: Scene, config: TruthConfig, servos: Sequence[ServoConfig] = ()
    ) -> None:
        self.config = config
        self.model = Model(rig_scene(scene, config.wheel_inertia_scale))
        # The compiled fast path (equal to the reference right-hand side to round-off,
        # tests/model/test_fast.py, test_fast_rig.py) keeps the truth ahead of real time on a
        # loaded laptop. A scene too stiff for one RK4 step per dt_s (a stiffer truth, an
        # identification's trial) takes substeps within the stability limit instead of failing.
        max_dt = stable_step(self.model, config.dt_s)
        self.stepper = Stepper(self.model, max_dt=max_dt, fast=True)
        self.dt_s = config.dt_s
        names = [s.name for s in scene.strings]
        self.servo_strings: dict[int, int] = {}
        offsets_rad = config.servo_zero_offset_rad or (0.0,) * len(servos)
        self.servo_offset_m = {
            s.id: s.length_sign * s.pulley_radius_m * off
            for s, off in zip(servos, offsets_rad, strict=True)
        }
        for servo in servos:
            if not servo.string:
                continue
            if servo.string not in names:
                raise RigSetupError(
                    f"servo '{servo.name}' (ID {servo.id}): string '{servo.string}' is not in "
                    f"scene {scene.name} (strings: {', '.join(names)})"
                )
            self.servo_strings[servo.id] = names.index(servo.string)
        st = self.model.structure
        self.scene_nodes = [st.primary[name] for name in scene.node_names]
        self.node_names = list(scene.node_names)
        self._frame = self._frame_nodes(scene, config.imu_frame_nodes)
        self.gravity_m_s2 = np.array(config.imu_gravity_m_s2, dtype=float)
        self.rest_length_m = np.array([s.rest_length(0.0) for s in scene.strings])
        self.wheel_input_rad_s = np.zeros(len(self.model.wheel_bars))
        self.u = self.model.pack_input(self.rest_length_m, self.wheel_input_rad_s)
        self.torque_driven = torque_driven(scene)
        self.held = self.torque_driven
        self._J3 = self.model.J3[self.model.wheel_bars]
        self._check_frame()
        # a step's servo turns add pieces: room for PIECES_PER_STEP of them per step
        steps = int(math.ceil((config.imu_latency_s + MAX_BACKLOG_S) / self.dt_s)) + 2
        depth = PIECES_PER_STEP * steps
        self._history: deque = deque(maxlen=depth)
        self._record: list | None = None
        self._x0 = self.stepper.x.copy()
        self.set_state(self._x0)

    def _frame_nodes(self, scene: Scene, names: Sequence[str]) -> list[int]:
        unknown = [n for n in names if n not in scene.node_names]
        if unknown:
            raise RigSetupError(
                f"sim.truth.imu_frame_nodes: node(s) {unknown} not in scene {scene.name} "
                f"(nodes: {', '.join(scene.node_names)})"
            )
        return [self.model.structure.primary[n] for n in names]

    def _check_frame(self) -> None:
        N, _ = self.model.nodes(self.stepper.x)
        a, b, c = (N[:, i] for i in self._frame)
        x = b - a
        if np.linalg.norm(np.cross(x, c - a)) < 1e-9 * max(np.dot(x, x), 1e-12):
            raise RigSetupError(
                "sim.truth.imu_frame_nodes: the three nodes are on one line, they define no plane"
            )

    # --- stepping -----------------------------------------------------------------------------
    def set_state(self, x: np.ndarray) -> None:
        """Replace the present state (layout of ``self.model``); the IMU history restarts."""
        self.stepper.x = np.array(x, dtype=float)
        self._history.clear()
        self._history.append((self.stepper.t, self.stepper.x.copy(), self.u, self.u))

    def reset(self) -> None:
        """Back to the scene's initial state (nodes, velocities, rest lengths), wheels at rest;
        the truth's clock runs on."""
        self.rest_length_m[:] = [s.rest_length(0.0) for s in self.model.scene.strings]
        self.wheel_input_rad_s[:] = 0.0
        self.u = self.model.pack_input(self.rest_length_m, self.wheel_input_rad_s)
        self.held = self.torque_driven
        self.set_state(self._x0)

    def release(self) -> bool:
        """Let the structure go (see the module docstring); returns whether it was held."""
        held, self.held = self.held, False
        return held

    @property
    def t_s(self) -> float:
        """Truth time, s."""
        return self.stepper.t

    def step(
        self,
        string_lengths_m: Mapping[int, float],
        wheel_speeds_rad_s: Sequence[float],
        turns: Sequence[tuple[float, Mapping[int, float]]] = (),
    ):
        """Advance by one step ``dt_s`` to the devices' outputs at the step's end.

        The rest lengths move in a straight line from where the last step left them to the
        servos' lengths at each of ``turns`` and then at the step's end, the physics stepped
        through each piece (first-order hold on the servos' own path: a servo that stops
        within a step stops the string then, where one line over the step would spread the
        move's corners over it, shifted by a part of the step the phase of the host's ticks
        held for a whole run). A speed-driven truth's spins move in a
        straight line over the whole step (the board's speeds change smoothly); a torque-driven
        truth's speed loop holds its torque over it.

        Parameters
        ----------
        string_lengths_m : mapping servo ID -> float, m
            The servos' string lengths at the step's end (those without a string are ignored).
        wheel_speeds_rad_s : sequence of float, rad/s
            The wheel board's true speeds at the step's end, board wheel order.
        turns : sequence of (float, mapping servo ID -> float)
            Times (s, within the step, ascending) where a servo's path bends, with every
            servo's string length then, m.
        """
        t0, t_end = self.stepper.t, self.stepper.t + self.dt_s
        wheel_start = self.wheel_input_rad_s.copy()
        self.wheel_input_rad_s[:] = self._board_order(wheel_speeds_rad_s)
        torque = None
        if self.torque_driven:  # the ideal speed loop's torque (module docstring)
            spin = self.model.wheel_speeds(self.stepper.x, self.u)
            torque = self._J3 * (self.wheel_input_rad_s - spin) / self.dt_s
            self.u = self.model.pack_input(self.rest_length_m, torque)
        points, last = [], t0
        for t, lengths in turns:
            if last + MIN_PIECE_S < t < t_end - MIN_PIECE_S:
                points.append((t, lengths))
                last = t
        for t, lengths in [*points, (t_end, string_lengths_m)]:
            share = (t - t0) / self.dt_s
            spins = wheel_start + share * (self.wheel_input_rad_s - wheel_start)
            self._piece(t - self.stepper.t, lengths, spins if torque is None else torque)
        self.stepper.t = t_end  # the pieces' sum drifts from the step by round-off
        if self._record is not None:
            self._record.append(
                (
                    self.stepper.t,
                    self.nodes(),
                    self.attitude(),
                    self.wheel_speeds_rad_s(),
                    self.rest_length_m.copy(),
                )
            )

    def _piece(self, h: float, string_lengths_m: Mapping[int, float], wheel) -> None:
        """Step the physics ``h`` s to the servos' lengths and the wheels' input (spins or
        torques) at the piece's end, in a straight line from the last piece's."""
        u_start = self.u
        lag = self.config.servo_lag_s
        gain = 1.0 if lag <= 0 else 1.0 - math.exp(-h / lag)
        for servo_id, index in self.servo_strings.items():
            target = string_lengths_m[servo_id] - self.servo_offset_m[servo_id]
            self.rest_length_m[index] += gain * (target - self.rest_length_m[index])
        if self.torque_driven:  # the torque is held over the piece
            u_start = self.model.pack_input(u_start[: self.model.alpha], wheel)
        self.u = self.model.pack_input(self.rest_length_m, wheel)
        x = self.stepper.step(h, u_start, self.u)
        if self.held:  # the mount: the structure where it started, the wheels as they spin
            L = self.model.layout
            x = self._x0.copy()
            x[L.theta], x[L.omega] = self.stepper.x[L.theta], self.stepper.x[L.omega]
            self.stepper.x = x
        self._history.append((self.stepper.t, x.copy(), u_start, self.u))

    def _board_order(self, speeds: Sequence[float]) -> np.ndarray:
        """Board speeds (rad/s) as the scene's wheels': the first n_w; missing ones 0."""
        out = np.zeros(len(self.wheel_input_rad_s))
        given = np.asarray(speeds, dtype=float)[: len(out)]
        out[: len(given)] = given
        return out

    # --- read-outs ----------------------------------------------------------------------------
    def wheel_speeds_rad_s(self) -> np.ndarray:
        """The truth's wheel spins now, shape (n_w,), rad/s (scene wheel order)."""
        return self.model.wheel_speeds(self.stepper.x, self.u)

    def nodes(self, x: np.ndarray | None = None) -> np.ndarray:
        """Scene node positions, shape (3, n_scene), m (state ``x``, default the present)."""
        N, _ = self.model.nodes(self.stepper.x if x is None else x)
        return N[:, self.scene_nodes]

    def attitude(self, N: np.ndarray | None = None) -> np.ndarray:
        """IMU frame axes in the world frame, shape (3, 3), of model nodes ``N`` (3, n); for
        ``N`` of shape (3, n, k) (k samples) shape (3, 3, k)."""
        if N is None:
            N, _ = self.model.nodes(self.stepper.x)
        a, b, c = (N[:, i] for i in self._frame)
        x = (b - a) / np.linalg.norm(b - a, axis=0)
        z = np.cross(x, c - a, axis=0)
        z /= np.linalg.norm(z, axis=0)
        return np.stack((x, np.cross(z, x, axis=0), z), axis=1)

    def frame_motion(self, N, N_dot, N_ddot):
        """Rate (body axes, rad/s), specific force (body axes, m/s^2) and attitude of the IMU
        frame for model nodes, velocities and accelerations (3, n, k): shapes (k, 3), (k, 3)
        and (k, 3, 3)."""
        R = np.moveaxis(self.attitude(N), -1, 0)
        R_ahead = np.moveaxis(self.attitude(N + FD_STEP_S * N_dot), -1, 0)
        W = np.einsum("kji,kjl->kil", R, R_ahead - R) / FD_STEP_S  # R^T R_dot: skew to O(h)
        omega = 0.5 * np.stack([W[:, 2, 1] - W[:, 1, 2], W[:, 0, 2] - W[:, 2, 0],
                                W[:, 1, 0] - W[:, 0, 1]], axis=1)  # fmt: skip
        a, b = self._frame[0], self._frame[1]
        accel = 0.5 * (N_ddot[:, a] + N_ddot[:, b]).T - self.gravity_m_s2
        return omega, np.einsum("kji,kj->ki", R, accel), R

    def tensions_N(self) -> np.ndarray:
        """String tensions now, shape (alpha,), N."""
        st = self.model.structure
        N, N_dot = self.model.nodes(self.stepper.x)
        S = N[:, st.string_end] - N[:, st.string_start]
        S_dot = N_dot[:, st.string_end] - N_dot[:, st.string_start]
        gamma = string_force_densities(self.model, S, S_dot, self.rest_length_m)
        return gamma * np.linalg.norm(S, axis=0)

    def servo_tensions_N(self) -> dict[int, float]:
        """Tension of the string each servo winds, servo ID -> N."""
        tensions = self.tensions_N()
        return {sid: float(tensions[i]) for sid, i in self.servo_strings.items()}

    def imu_truth(self, t_s: float) -> ImuTruth:
        """What the IMU frame does at ``t_s - imu_latency_s``: the state interpolated between
        the truth's steps around that time (a sensor samples on its own clock, not on the
        truth's 5 ms steps; the linear interpolation's error, ``a dt^2 / 8``, is far below the
        IMU's noise), under the step's input at that time; after the newest step, the newest."""
        when = t_s - self.config.imu_latency_s
        entries = list(self._history)
        later = next((i for i, e in enumerate(entries) if e[0] >= when - 1e-12), None)
        if later is None:
            t, x, _, u = entries[-1]
        elif later == 0:
            t, x, _, u = entries[0]
        else:
            (t_a, x_a, _, _), (t_b, x_b, u_a, u_b) = entries[later - 1], entries[later]
            share = (when - t_a) / (t_b - t_a)
            t, x, u = when, x_a + share * (x_b - x_a), u_a + share * (u_b - u_a)
        N, N_dot = self.model.nodes(x)
        q_ddot = self.stepper.dynamics(t, x, u)[self.model.layout.q_dot].reshape(3, -1)
        N_ddot = np.asarray(self.model.U2 @ q_ddot.T).T
        omega, force, R = self.frame_motion(*(v[..., None] for v in (N, N_dot, N_ddot)))
        return ImuTruth(omega[0], force[0], R[0])

    def has_imu_truth(self, t_s: float) -> bool:
        """The truth has stepped up to what the IMU shows at ``t_s`` (see :meth:`imu_truth`)."""
        return self.t_s >= t_s - self.config.imu_latency_s - 1e-12

    # --- recording ----------------------------------------------------------------------------
    def start_recording(self) -> None:
        """Record every following step (see :meth:`recording`)."""
        self._record = []

    def recording(self) -> TruthRecord:
        """The steps recorded since :meth:`start_recording` (a snapshot; recording goes on)."""
        rows = list(self._record or [])
        n_w, alpha = len(self.wheel_input_rad_s), len(self.rest_length_m)
        n = len(self.scene_nodes)

        def stack(i, shape):
            return np.array([r[i] for r in rows]) if rows else np.zeros((0, *shape))

        return TruthRecord(
            t_s=stack(0, ()),
            N=stack(1, (3, n)),
            R_wb=stack(2, (3, 3)),
            omega_w_rad_s=stack(3, (n_w,)),
            rest_length_m=stack(4, (alpha,)),
            node_names=self.node_names,
        )
