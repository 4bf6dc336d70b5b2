"""Software-in-the-loop Monte Carlo on the simulated rig's models.

What ``gyrotens sil`` runs (:func:`report`; the simulated clock's runs go through
:mod:`gyrohost.parallel` when ``--workers`` or ``--scheduler`` is given, the real-time ones
always one after the other). Besides the printed
table, the step-by-step figure of NEES and NIS with their bounds
(:mod:`gyrohost.plots.consistency`) goes to ``--plot``, by default ``OUT/consistency.png``.

In process, on a simulated clock (deterministic timing): the rig's truth model
(:class:`gyrohost.simrig.truth.Truth`: speed-controlled wheels, servo calibration, its own IMU frame
and finite-difference rate, gravity felt by the IMU) stepped at its ``dt_s`` under the scene's
rest-length schedule; the servos follow the command as the emulated MX-12W does (its position
loop's lag, :func:`.emulator_keys.emulated_servo_lag_s`, at most at its speed) and report
quantised positions through their calibration; the IMU samples go through the rig's
BWT61CL emulator (noise densities, biases, int16 quantisation of the wire format; seed = run
number) and are parsed back by the IMU driver's parser; the wheels are spun by the rig's
wheel-board emulator (spun up to the scene's spins before t = 0, wheel angles drawn from the
seed), whose TELEMETRY frames are read off its pty and decoded with the protocol's decoder: the
speeds carry the encoder's quantisation noise through the firmware's low-pass. The filter takes
the latest frame at every IMU sample (decimated from 500 Hz to its 100 Hz: the low-pass's 8 ms
would correlate frames 2 ms apart). Scored at every IMU sample against the truth state: NEES
(full state, on the constraint manifold), NIS per source, tilt error. The filter's keys: the
simulated rig's noise (:func:`.emulator_keys.emulator_keys`), :data:`RIG_MODEL_KEYS` over them,
then ``--estimator FILE``'s (:func:`sil_keys`).

``--realtime`` instead plays the schedule on the real-time simulated rig through the run loop
(``run_simulated``: ptys, drivers, arrival time stamps, the IMU's fused at its reconstructed
grid) and scores the replayed log against its ``truth`` stream (positions, wheel speeds, rest
lengths: no velocities); on a loaded machine the truth lags by up to 0.2 s, and its stream.
"""

import os
import select
import sys
import time
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np

from gyrohost import parallel
from gyrohost.drivers.mx12 import lag_error_after
from gyrohost.estimator import streams
from gyrohost.estimator.config import EXACT_IMU_TIMES
from gyrohost.estimator.consistency import (
    average_bounds,
    observed_blocks,
    observed_nees,
    sample_initial,
    state_of_truth,
)
from gyrohost.resources import resolve
from gyrohost.run.log import read_stream
from gyrohost.run.replay import prepare
from gyrohost.sil.emulator_keys import emulated_servo_lag_s, emulator_keys
from gyrohost.sil.montecarlo import (
    START_SEED_OFFSET,
    ScoredRun,
    nees_average,
    nis_average,
    sampled_truth,
    score_run,
    summarise,
)
from gyrohost.simrig.config import sim_config, with_sim_keys, with_truth_scene

from .errors import SilError

DEFAULT_RUNS = 20  # runs a SIL simulates or records when --runs is not given
WHEEL_SPIN_UP_S = 2.0  # the wheel board spins up (ramp and lag) before the run starts, s
PTY_WAIT_S = 1.0  # longest wait for the wheel board's frames to come through its pty, s
# Keys for the in-process SIL (on top of emulator_keys), each checked by the marginal NEES of its
# block (docs/estimator.md). The rig's truth has no random forces and moves its rest lengths as
# the servos do (the lag at most at their speed, as the filter's); node noise as the rig's. The
# servos here are exactly the filter's motion (no read off it, no goal-step spread or delay, no
# hold): reads to the step's quantisation (4.4 um), and a walk of 1e-13 m^2/s, set for what the
# old 50 ms lag's model missed where the dynamics pin the rest lengths; the exact motion leaves
# far less (reports/estimator-history.md, "The servos as a position loop"). Wheels as the rig's.
RIG_MODEL_KEYS = {
    "servo_length_std_m": 4.4e-6,
    "servo_time_std_s": 0.0,
    "rest_psd_m2_s": 1e-13,
    "rest_hold_std_m": 0.0,
    "servo_step_std_ratio": 0.0,
    "servo_delay_std_s": 0.0,
    "rest_jitter_psd_m2_s": 0.0,
    **EXACT_IMU_TIMES,  # the SIL's samples carry their own times
}


def seeded(config, seed):
    """``config`` with its simulated IMU's and wheels' noise and its servos' stops from ``seed``."""
    for table in ("imu", "wheels", "servos"):
        config = with_sim_keys(config, table, seed=seed)
    return config


def record_run(config, seed, folder, duration_s=3.0, estimator=None):
    """One run of the paper's schedule on the simulated rig with its noise from ``seed``
    (:func:`seeded`); ``estimator``: a TOML file whose ``[estimator]`` keys override the
    configuration's."""
    from gyrohost.control.presets import paper
    from gyrohost.estimator.config import for_rig
    from gyrohost.run import run_simulated
    from gyrotensegrity import Model, load_scene

    cfg = seeded(config, seed)
    schedule = paper(Model(load_scene(cfg.scene_path)), duration_s=duration_s)
    result = run_simulated(cfg, schedule, folder, estimator=for_rig(cfg, estimator))
    if not result.completed:  # a diverged filter completes: the scores say how far it is off
        raise SilError(f"{folder}: the run stopped: {result.reason}")
    return folder


def replayed_config(folder, estimator=None):
    """The estimator configuration a log ran with, its keys overridden by the ``[estimator]``
    table of the file ``estimator`` (None: the log's own, as :func:`prepare` takes it)."""
    if estimator is None:
        return None
    from gyrohost.estimator.config import config_from_dict, read_table
    from gyrohost.run.log import read_meta

    keys = {**read_meta(folder).get("estimator", {}), **read_table(estimator)}
    return config_from_dict(keys, str(estimator))


def _truth_at(truth, t, columns):
    return np.array([np.interp(t, truth["t_s"], truth[c]) for c in columns])


def score_log(folder, estimator=None, config=None, start_seed=None) -> ScoredRun:
    """Replay a simulated-rig log and score it against its ``truth`` stream (positions, wheel
    speeds and rest lengths: NEES over those, the positions in the tangent space of the bar
    lengths; the velocity entries of ``x_true`` are the estimate's own); ``estimator``: a TOML
    file whose ``[estimator]`` keys override the log's; ``config``: an
    :class:`~gyrohost.estimator.config.EstimatorConfig` replayed instead of either.

    ``start_seed`` None: the filter starts where ``gyrotens replay`` starts it, on the
    simulated rig the truth itself (the rig starts exactly in the scene's shape); an int: off
    the truth by a draw from the filter's initial covariance (``numpy`` seed), as a Monte Carlo
    run starts (:func:`score_rig_model_run`). Either way the structure's translation, which no
    sensor sees, is not scored (:func:`~gyrohost.estimator.consistency.scored_positions`)."""
    ekf, data = prepare(folder, config=config or replayed_config(folder, estimator))
    model, L = ekf.model, ekf.layout
    truth = read_stream(folder, "truth")
    scene_nodes = list(model.scene.node_names)
    node_cols = [f"{name}_{a}_m" for name in scene_nodes for a in "xyz"]
    wheel_cols = [f"omega_{i}_rad_s" for i in range(L.n_wheels)]
    rest_cols = [streams.rest_column(s.name) for s in model.scene.strings]

    def truth_at(e):
        N = _truth_at(truth, e.t, node_cols).reshape(len(scene_nodes), 3).T
        omega, rest = _truth_at(truth, e.t, wheel_cols), _truth_at(truth, e.t, rest_cols)
        x_true = state_of_truth(e, e.x, N, omega, rest)
        N_all, _ = e.batch_nodes(x_true[None, :])
        R_true, _ = e.imu.frame(N_all, np.zeros_like(N_all))
        return x_true, R_true[0]

    def partial_nees(e, x_true):
        return observed_nees(e, e.x, e.P, x_true)

    if start_seed is not None:
        rng = np.random.default_rng(start_seed)
        ekf.start_at(sample_initial(ekf, truth_at(ekf)[0], rng))
    return score_run(ekf, data, truth_at, partial_nees, blocks_of=observed_blocks)


def rig_model_run(
    config, seed, duration_s=3.0, command_times_s=None, schedule_times_s=None, schedule=None
):
    """One in-process run on the rig's truth model and sensor emulators (see module docstring).

    The truth runs ``[sim.truth] scene`` when set and the IMU is turned by ``[sim.truth]
    imu_rotation_deg`` beyond the configuration's mounting, as on the real-time simulated rig;
    the host's commands and the returned model are the configuration's scene's.

    ``command_times_s`` (increasing, s): when the commands reach the servos (at the first truth
    step from then on; default: every 10 ms), each the schedule at its time or at its entry of
    ``schedule_times_s`` (the tick that made it, when the servos get it later).

    ``schedule`` (a :class:`gyrohost.control.schedule.Schedule`): played instead of the scene's
    rest lengths, its wheel speeds sent to the wheel board whenever the command changes (the
    board spun up to its speeds at 0), as the run loop plays it.

    Returns
    -------
    data : dict of structured arrays (streams of :mod:`.streams`)
    truth_x : ndarray, shape (k, n), true filter states at every truth step (``dt_s`` apart)
    truth_R : ndarray, shape (k, 3, 3), true sensor axes at every truth step
    frames : ndarray, shape (f, 1 + n_w), every telemetry frame from t = 0: the board's own
        time (its clock less its time at t = 0), s, and the speeds, rad/s
    dt_s : float, the truth's step, s
    """
    from gyrohost.simrig.imu_emu import Bwt61Emulator
    from gyrohost.simrig.truth import Truth, torque_driven, truth_scene
    from gyrotensegrity import Model, load_scene

    config = seeded(config, seed)
    model = Model(load_scene(config.scene_path))
    sim = sim_config(config)
    scene = truth_scene(config)
    if torque_driven(scene):
        raise SilError(
            f"truth scene {scene.name}: [rig_fidelity] motor_reaction drives the wheels by "
            "torque, which the in-process SIL's wheel board does not (it plays their speeds): "
            "run it on the real-time simulated rig (gyrotens run --sim)"
        )
    truth = Truth(scene, replace(sim.truth, servo_lag_s=0.0), config.servos.servo)
    emu = Bwt61Emulator(sim.imu, config.imu, rotation_deg=sim.truth.imu_rotation_deg)
    servos = [s for s in config.servos.servo if s.string]
    strings = [s.name for s in model.scene.strings]
    inputs = _commands(model, schedule)
    board = _WheelBoard(sim.wheels, inputs(0.0)[1], np.random.default_rng(seed + 5_000_003))
    try:
        rows, truth_x, truth_R = _rig_model_rows(
            model, truth, emu, board, servos, duration_s, command_times_s, schedule_times_s,
            inputs, emulated_servo_lag_s(config),
        )  # fmt: skip
    finally:
        board.close()
        emu.close()  # its pty pair: only its encoder was used
    n_w = len(model.spin0)
    columns = {
        streams.IMU: streams.imu_columns(),
        streams.WHEELS: streams.wheels_columns(n_w),
        streams.SERVOS: streams.servos_columns([s.string for s in servos]),
        streams.COMMAND: streams.command_columns(strings, n_w),
    }
    data = {}
    for name, values in rows.items():
        arr = np.array(values)
        data[name] = np.empty(len(arr), dtype=[(c, "f8") for c in columns[name]])
        for j, c in enumerate(columns[name]):
            data[name][c] = arr[:, j]
    frames = np.array([f for f in board.frames if f[0] >= -1e-9])
    return model, data, np.array(truth_x), np.array(truth_R), frames, truth.dt_s


def _commands(model, schedule=None):
    """``inputs(t)``: the host's rest lengths (alpha,) m and wheel speeds (n_w,) rad/s at
    schedule time ``t``: the scene's (its spins held), those ``schedule`` plays in their place."""
    if schedule is None:
        return lambda t: (model.input_at(t)[: model.alpha], model.spin0)
    strings, wheels = schedule.bind(model), schedule.bind_wheels(model)

    def inputs(t):
        rest, spins = model.input_at(t)[: model.alpha], np.array(model.spin0, float)
        rest[strings], spins[wheels] = schedule(t), schedule.wheel_speeds(t)
        return rest, spins

    return inputs


def _rig_model_rows(
    model, truth, emu, board, servos, duration_s, command_times_s, schedule_times_s, inputs, lag_s
):
    """Step truth, servos, IMU emulator and wheel board; the streams and the truth samples.
    ``inputs``: the host's commands (:func:`_commands`), wheel speeds sent to the board when
    they change; ``lag_s``: the servos' position-loop lag, s."""
    from gyrohost.drivers.imu import Bwt61Parser
    from gyrohost.drivers.mx12 import length_to_steps, steps_to_length
    from gyrohost.estimator.layout import from_model_state

    parser = Bwt61Parser()
    strings = [s.name for s in model.scene.strings]
    servo_strings = [strings.index(s.string) for s in servos]
    pairs = list(zip(servos, servo_strings, strict=True))
    position = {s.id: s.length_at_zero_m for s in servos}
    spins = board.commanded  # what the host commands
    truth.wheel_input_rad_s[:] = board.true_speeds()  # spun up before t = 0
    truth.u = truth.model.pack_input(truth.rest_length_m, truth.wheel_input_rad_s)
    dt = truth.dt_s
    imu_every = int(round(0.01 / dt))
    rows = {streams.IMU: [], streams.WHEELS: [], streams.SERVOS: [], streams.COMMAND: []}
    truth_x, truth_R = [], []
    sends = np.arange(0.0, duration_s + dt, 0.01) if command_times_s is None else command_times_s
    made = sends if schedule_times_s is None else schedule_times_s
    sent, command = 0, model.input_at(0.0)[: model.alpha]
    for k in range(int(round(duration_s / dt)) + 1):
        t = k * dt
        wheels = board.advance(t)
        while sent < len(sends) and sends[sent] <= t + 1e-9:  # held until the next one
            command, wanted = inputs(made[sent])
            if not np.array_equal(wanted, spins):
                spins = wanted
                board.command(spins, t)
            rows[streams.COMMAND].append([sends[sent], *command, *spins])
            sent += 1
        reported = {  # the servo's position now, quantised to its steps
            s.id: steps_to_length(s, round(length_to_steps(s, position[s.id]))) for s in servos
        }
        imu = truth.imu_truth(t)
        if k % imu_every == 0:
            (sample,) = parser.feed(emu.encode_sample(imu), int(round(t * 1e9)))
            rows[streams.IMU].append(
                [t, *sample.omega_rad_s, *sample.accel_m_s2, *sample.euler_rad]
            )
            rows[streams.WHEELS].append([t, *wheels])  # the latest frame
            if k % (4 * imu_every) == 0:
                rows[streams.SERVOS].append([t, *(reported[s.id] for s in servos)])
        # the truth at every step (the real-time effects score at stamps off the IMU grid); its
        # plant has speed-driven wheels: its state has no spins, its input has; the true rest
        # lengths are the servos' (continuous, unquantised) positions now
        rest = truth.rest_length_m.copy()
        rest[servo_strings] = [position[s.id] for s in servos]
        u = truth.model.pack_input(rest, board.true_speeds())
        truth_x.append(from_model_state(truth.model, truth.stepper.x, u, emu.gyro_bias_rad_s))
        truth_R.append(imu.R_wb @ emu.R_bs)  # the sensor axes, as the filter's attitude
        # goals sent within the step move the servos from their send on
        within = np.searchsorted(sends, t + dt - 1e-9, "left")
        later = [(sends[j] - t, inputs(made[j])[0]) for j in range(sent, within)]
        ends, paths = servo_paths(pairs, position, command, later, dt, lag_s)
        turns = [(t + e, {sid: p[j] for sid, p in paths.items()}) for j, e in enumerate(ends[:-1])]
        position = {sid: p[-1] for sid, p in paths.items()}
        board.dev.tick(t + dt)  # the wheels' speeds at the step's end, where the truth goes
        truth.step(dict(position), board.true_speeds(), turns)
    return rows, truth_x, truth_R


SERVO_PIECES = np.linspace(0.2, 1.0, 5)
"""Where in a truth step the in-process servos' paths bend at least (fractions of the step): a
lag's curve against the chord of a whole step is off by ``e h^2 / (8 lag^2)``, 26 um for a 1.5
mm goal step at 13 ms; against a fifth of the step, a twenty-fifth of that."""


def servo_paths(pairs, start_m, goals_m, later, dt_s, lag_s):
    """The servos' string lengths over a step of ``dt_s`` s from ``start_m`` (servo ID -> m)
    under the goals ``goals_m`` (every string, m) and those ``later`` sends (offset in the
    step, s; goals) put in effect: the lag at most at each servo's speed, exactly. Returns the
    offsets where the paths bend (:data:`SERVO_PIECES` and the sends'; the last the step's
    end) and each servo's lengths there (ID -> list)."""
    ends = sorted({*np.round(SERVO_PIECES * dt_s, 12), *(offset for offset, _ in later)})
    paths = {}
    for servo, i in pairs:
        x, last, goal, pending = start_m[servo.id], 0.0, goals_m[i], list(later)
        path = []
        for end in ends:
            x = goal - float(lag_error_after(goal - x, end - last, lag_s, servo.max_speed_m_s))
            last = end
            while pending and pending[0][0] <= end + 1e-12:
                goal = pending.pop(0)[1][i]
            path.append(x)
        paths[servo.id] = path
    return ends, paths


class _WheelBoard:
    """The rig's wheel-board emulator on the simulated clock, spun up to ``spins`` (scene
    order) by ``t = 0``, its telemetry read off the pty and decoded."""

    def __init__(self, wheels, spins, rng):
        from gyrohost.drivers import wheelproto as wp
        from gyrohost.simrig.wheel_emu import WheelBoardEmulator

        self.wp = wp
        self.sign = np.array(wheels.spin_sign[: len(spins)], float)
        self.dev = WheelBoardEmulator(wheels)
        self.dev.angle_rad = list(rng.uniform(0.0, 2.0 * np.pi, wp.N_WHEELS))
        self.fd = os.open(self.dev.slave_path, os.O_RDONLY | os.O_NONBLOCK)
        self.decoder = wp.FrameDecoder()
        t0 = -WHEEL_SPIN_UP_S
        self.dev.tick(t0)
        self.heartbeat = wp.encode("HEARTBEAT")
        self.command(spins, t0)
        self.latest = np.zeros(len(spins))
        self.frames: list = []  # (board time since t = 0, s; speeds) of every frame
        for k in range(1, int(WHEEL_SPIN_UP_S * 100) + 1):
            self.advance(t0 + 0.01 * k)  # in 10 ms chunks: the pty holds a few kB

    def command(self, spins, t_s):
        """Send the wheels' speeds (scene order), rad/s, at ``t_s``."""
        board = np.zeros(self.wp.N_WHEELS)
        board[: len(spins)] = self.sign * spins
        targets = {f"w{i}_mrad_s": int(round(1e3 * w)) for i, w in enumerate(board)}
        self.dev.handle_rx(self.wp.encode("SET_SPEEDS", **targets), t_s)
        self.commanded = np.array(spins, float)

    def advance(self, t_s):
        """Tick the board to ``t_s``; return the latest reported speeds (scene order), rad/s.
        Each call is a tick of the host's control loop: it keeps the board's heartbeat."""
        self.dev.handle_rx(self.heartbeat, t_s)
        self.dev.tick(t_s)
        # the pty hands the bytes over asynchronously, later on a loaded machine: wait for every
        # frame the board sent, so the stream is the same at any load (a frame a step late
        # breaks the 10 ms sample sequence the wheel noise model assumes)
        deadline = time.monotonic() + PTY_WAIT_S
        while len(self.frames) < self.dev.telemetry_sent and time.monotonic() < deadline:
            if select.select([self.fd], [], [], 0.01)[0]:
                self._decode(os.read(self.fd, 65536))
        return self.latest

    def _decode(self, data):
        for msg in self.decoder.feed(data):
            if msg.name == "TELEMETRY":
                w = [msg.fields[f"w{i}_mrad_s"] * 1e-3 for i in range(len(self.latest))]
                self.latest = self.sign * np.array(w)
                self.frames.append((msg.fields["t_us"] * 1e-6 - WHEEL_SPIN_UP_S, *self.latest))

    def true_speeds(self):
        """The wheels' true speeds (scene order), rad/s."""
        return self.sign * np.array(self.dev.wheel_speeds_rad_s()[: len(self.latest)])

    def close(self):
        os.close(self.fd)
        self.dev.close()


def score_rig_model_run(config, seed, duration_s=3.0, overrides=None) -> ScoredRun:
    """Filter one :func:`rig_model_run` and score it against its truth; ``overrides``: estimator
    keys on top of :func:`.emulator_keys.emulator_keys`."""
    from gyrohost.estimator.config import config_from_dict
    from gyrohost.estimator.ekf import TensegrityEKF

    model, data, truth_x, truth_R, _, dt_s = rig_model_run(config, seed, duration_s)
    est_cfg = config_from_dict({**emulator_keys(config), **(overrides or {})})
    # the initial estimate is drawn around the truth with the filter's initial covariance (an
    # error-free start scores the unobservable centre of mass at zero error for the whole run)
    ekf = TensegrityEKF(model, est_cfg)
    rng = np.random.default_rng(seed + START_SEED_OFFSET)
    ekf = TensegrityEKF(model, est_cfg, x0=sample_initial(ekf, truth_x[0], rng))
    if ekf.layout.n_mounting:  # its truth: the configured mounting's error, all run
        error = np.tile(mounting_error(config, est_cfg), (len(truth_x), 1))
        truth_x = np.hstack([truth_x, error])
    if ekf.layout.n_accel_bias:  # its truth: the emulator's drawn bias, all run
        truth_x = np.hstack(
            [truth_x, np.tile(emulated_accel_bias(config, seed), (len(truth_x), 1))]
        )
    return score_run(ekf, data, sampled_truth(truth_x, truth_R, dt_s))


def sil_keys(estimator=None) -> dict:
    """The simulated clock's filter keys on top of :func:`.emulator_keys.emulator_keys`, each
    layer overriding the keys it names: :data:`RIG_MODEL_KEYS`, then the ``[estimator]`` table
    of the file ``estimator`` (docs/estimator.md). The rig configuration's own ``[estimator]``
    table is left out: it describes the real-time rig (ptys, arrival times, goal steps), which
    the simulated clock has none of."""
    from gyrohost.estimator.config import file_keys

    return {**RIG_MODEL_KEYS, **file_keys(estimator)}


def emulated_accel_bias(config, seed) -> np.ndarray:
    """The accelerometer bias (3,) m/s^2, sensor axes, that the simulated IMU of ``config``
    draws with the noise of ``seed`` (:func:`seeded`): the same draw as the run's."""
    from gyrohost.simrig.imu_emu import Bwt61Emulator

    config = seeded(config, seed)
    emu = Bwt61Emulator(sim_config(config).imu, config.imu)
    emu.close()  # its pty pair: only its draw is wanted
    return emu.accel_bias_m_s2


def mounting_error(config, est_cfg) -> np.ndarray:
    """The simulated IMU's true mounting (``[imu] mounting_rpy_rad`` turned by ``[sim.truth]
    imu_rotation_deg``) less the filter's ``imu_mounting_rpy_rad``: roll, pitch, yaw (3,), rad."""
    from gyrohost.geometry import euler_zyx, wrap_angle
    from gyrohost.simrig.imu_emu import sensor_in_body

    rotation_deg = sim_config(config).truth.imu_rotation_deg
    true = sensor_in_body(config.imu.mounting_rpy_rad, rotation_deg)
    return wrap_angle(euler_zyx(true) - np.asarray(est_cfg.imu_mounting_rpy_rad))


def sil_results(
    config,
    runs,
    duration_s=3.0,
    realtime=False,
    out=None,
    score_only=False,
    executor=None,
    estimator=None,
    keys=None,
):
    """``runs`` SIL runs (seeds 1, 2, ...): in process on the simulated clock, each a case of
    ``executor`` (:class:`gyrohost.parallel.Executor`; default serial), or with ``realtime``
    recorded one after the other on the real-time simulated rig into ``out``/runNN
    (``score_only``: score logs already there) and scored from their logs; ``estimator``: a
    TOML file whose ``[estimator]`` keys the runs use (simulated clock: over :func:`sil_keys`;
    ``score_only``: the replays); ``keys``: estimator keys over those (simulated clock).
    Returns the :class:`ScoredRun` list."""
    if not realtime:
        overrides = {**sil_keys(estimator), **(keys or {})}
        task = partial(score_rig_model_run, config, duration_s=duration_s, overrides=overrides)
        return (executor or parallel.Executor(serial=True)).map(task, range(1, runs + 1))
    results = []
    for seed in range(1, runs + 1):
        folder = Path(out) / f"run{seed:02d}"
        if not score_only:
            if (folder / "meta.json").exists():
                raise SilError(f"{folder} exists; remove it or score it (--score-only)")
            record_run(config, seed, folder, duration_s, estimator)
        start_seed = seed + START_SEED_OFFSET
        results.append(score_log(folder, estimator if score_only else None, start_seed=start_seed))
        print(f"run {seed}: {len(results[-1].t_s)} IMU samples scored", file=sys.stderr)
    return results


def recorded_runs(out) -> int:
    """How many runs ``--realtime`` recorded in ``out`` (``run01``, ``run02``, ... in a row).

    Raises
    ------
    SilError
        None there.
    """
    count = 0
    while (Path(out) / f"run{count + 1:02d}" / "meta.json").exists():
        count += 1
    if not count:
        raise SilError(f"{out}: no recorded runs to score (run01, run02, ... with meta.json)")
    return count


def report(args) -> dict:
    """Run and print the SIL table of ``args`` (:func:`add_arguments`); returns the figures."""
    from gyrohost.config import load_with_scene

    config = load_with_scene(args.config, args.overlay, args.scene)
    if args.truth_scene is not None:
        config = with_truth_scene(config, resolve("scene", args.truth_scene))
    runs = args.runs
    if runs is None:
        runs = recorded_runs(args.out) if args.realtime and args.score_only else DEFAULT_RUNS
    with parallel.from_args(args) as executor:
        results = sil_results(
            config, runs, args.duration, args.realtime, args.out, args.score_only,
            executor, args.estimator,
        )  # fmt: skip
    clock = "real-time rig through the run loop" if args.realtime else "simulated clock"
    print(f"--- SIL ({clock}): {len(results)} runs of the paper's schedule")
    figures = summarise(results, "[sil] ")
    from gyrohost.plots.consistency import plot_consistency  # matplotlib: not on the workers

    path = args.plot or Path(args.out) / "consistency.png"
    plot_consistency(*consistency_series(results), len(results), f"SIL ({clock})", path)
    print(f"[sil] step-by-step NEES and NIS with their bounds: {path}")
    return figures


def consistency_series(results):
    """The run-averaged NEES and the NIS of every source as
    :class:`~gyrohost.plots.consistency.Series` of the figure."""
    from gyrohost.plots.consistency import Series

    def series(name, t_s, values, dof):
        return Series(name, t_s, values, dof, average_bounds(dof, len(results)))

    nees = series("NEES", *nees_average(results))
    return nees, [series(f"NIS {s}", *nis_average(results, s)) for s in results[0].nis]
