"""Prediction-error fit: the rig's parameters that make the host's EKF predict its sensors best.

The output-error fit (:mod:`.fit`) simulates the rig from the log's inputs and compares the
simulation with the IMU; it has to know every input the structure felt. The wheels' speed loop
leaves each wheel off its setpoint by an error the reports see only through their quantisation
noise (docs/rig.md), and the D-bar's unstable roll mode grows that unknown input into a motion
no simulation from the logged speeds follows (docs/identification.md#limits).
Here the EKF runs the log instead (:func:`gyrohost.run.replay.started`, gate open), its process
model the scene of a parameter vector: it carries the wheels' error as the process noise of its
wheel states and corrects the state at every sample, so each innovation is the one-sample-ahead
prediction error of that scene. The cost is the innovations' negative log-likelihood: every
innovation whitened by its covariance ``S`` (:attr:`gyrohost.estimator.fusion.Innovation.
whitened`: unit variance when the scene is the rig's), of every source, and for each the
square root of its ``log det S`` less the sensor's ``log det R``
(:attr:`~gyrohost.estimator.fusion.Innovation.spread`, never negative). Without that term a
scene that widens ``S`` buys a smaller NIS, and the strings' damping falls low
(reports/identification-history.md, "Why the likelihood"). The fit is solved as the output-error
fit is, and moved to the smooth minimum of the valley where the strings' stiffness and damping
trade (:func:`.profile.strings_valley`: the cost is as rough along it, some ten units where a string
goes slack a sample earlier); its statistics are the output-error fit's (:func:`.fit.statistics`).

Parameters: those of :mod:`.params` that the filter's model or its inputs carry (the scene's
masses, inertias, stiffness and damping; the IMU mounting as the filter's
``imu_mounting_rpy_rad``; the servo lag as its ``servo_lag_s``; servo zero offsets added to the
reported and commanded lengths; accelerometer and gyro biases taken off the IMU's readings, the
gyro's on top of the filter's own bias state).
"""

import os
import pickle
import signal
import tempfile
import threading
import warnings
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass, replace
from multiprocessing import get_context, resource_tracker

import numpy as np
from scipy.linalg import LinAlgWarning

from gyrohost.config import RigConfig
from gyrohost.estimator import sample_feed, streams
from gyrohost.estimator.config import EstimatorConfig
from gyrohost.estimator.errors import EstimatorError
from gyrohost.geometry import rotation_zyx, turn_from_first
from gyrohost.ident import fit as output_fit
from gyrohost.ident import profile
from gyrohost.ident.errors import IdentDataError
from gyrohost.ident.logs import read_fused, windowed
from gyrohost.ident.params import Param, apply
from gyrohost.run.replay import started
from gyrotensegrity import Model, Scene

from .errors import FilterFitError

IMU_SOURCES = ("imu_rate", "imu_accel", "imu_angle")


def state_groups(est) -> tuple[str, ...]:
    """Parameter groups the filter ``est`` (EstimatorConfig) estimates as its own states: not
    fitted (a parameter and a state of the same bias cannot be told apart)."""
    return ("gyro-bias",) + (("accel-bias",) if est.init_accel_bias_std_m_s2 > 0.0 else ())


CHANNELS = tuple(f"{stream} {a}" for stream in ("gyro", "accel", "angle") for a in "xyz")
STREAMS = {"gyro": slice(0, 3), "accel": slice(3, 6), "angle": slice(6, 9)}
"""The IMU innovations' columns in :attr:`.fit.FitResult.residuals`: rate (rad/s), specific
force (m/s^2), the attitude's error as a rotation vector in world axes (rad)."""


ROLLED_OVER_RAD = np.radians(45.0)
"""How far the IMU's reported attitude may turn from its start within a fitted window before the
fit warns that the window runs past the D-bar's roll-over: on the real-time simulated rig the
windows whose sensor turned 6 to 25 degrees (and 9, with exact wheels) fitted every parameter of
the acceptance, a window to 90 degrees broke the filter and left J3 22 % off
(reports/identification-history.md, "On a real-time recording")."""
SUGGESTED_TURN_RAD = np.radians(30.0)
"""Where the warning suggests ending the window: the largest turn that fitted, rounded up."""


@dataclass(frozen=True)
class FilterRecording:
    """A log's streams as the filter fuses them (:func:`gyrohost.ident.logs.read_fused`),
    from the start of its ``lead_in`` phase (or its first sample) to its ``rampdown`` (or its
    end), at most ``until_s`` long."""

    name: str
    data: dict


def load(folder, until_s: float | None = None, warn=None) -> FilterRecording:
    """The :class:`FilterRecording` of the log folder ``folder``; rows not to be fused left out
    and told to ``warn`` (:func:`gyrohost.ident.logs.read_fused`).

    Raises
    ------
    IdentDataError
        The log cannot be read, too many of its rows are left out, or it holds fewer than two
        IMU samples in the window.
    """
    data = read_fused(folder, warn, every=False)  # the span is the phases', not the estimate's
    if streams.IMU not in data:
        raise IdentDataError(f"{folder}: stream '{streams.IMU}' missing")
    data, start = windowed(folder, data, until_s)
    if start is not None:
        # the filter starts at the earliest row (gyrotens replay's rule): the last wheel
        # report, servo position and command before the start set its start, the IMU is
        # fused from the start on
        data[streams.IMU] = data[streams.IMU][data[streams.IMU]["t_s"] >= start]
    if len(data[streams.IMU]) < 2:
        raise IdentDataError(f"{folder}: fewer than two IMU samples to fit")
    return FilterRecording(str(folder), data)


class FilterProblem(output_fit.WalledResiduals):
    """The whitened innovations of parameter vectors over the recordings (the interface of
    :class:`.fit.Problem`, which :func:`.fit.statistics` and :mod:`.profile` use).

    With ``workers`` > 1, :meth:`batch` runs the filters of its parameter vectors in that many
    processes (started at the first batch, ended by :meth:`close`): a Jacobian's columns, a
    profile's samples. Each process holds its own copy of the problem."""

    error = FilterFitError

    def __init__(
        self, scene: Scene, config: RigConfig, est, params: list, recs: list, workers: int = 1
    ):
        self.scene, self.config, self.params, self.recs = scene, config, params, recs
        self.est = replace(est, gate_probability=1.0)  # every sample in, every run alike
        self.servo_lag_s = est.servo_lag_s
        self.dynamic = np.ones(len(params), bool)  # every parameter needs a filter run
        self.workers = workers
        self._key, self._runs, self._pool = None, None, None
        self.simulations = 0
        self.failures: list[str] = []
        self._length = None  # residuals per evaluation: every sample's, as the first run gave
        self._spreads = None  # which of them are the spreads' square roots

    def applied(self, theta):
        return apply(self.scene, self.config, self.params, theta, self.servo_lag_s,
                     len(self.recs), self.est.imu_latency_s)  # fmt: skip

    def runs(self, theta) -> list:
        """Per recording, the innovations in fusion order and where the filter broke, or None
        (see :func:`_run`)."""
        key = tuple(np.asarray(theta, float))
        if key != self._key:
            a = self.applied(theta)
            est = replace(
                self.est,
                imu_mounting_rpy_rad=tuple(float(v) for v in a.mounting_rpy_rad),
                servo_lag_s=float(a.servo_lag_s),
                accel_psd_m2_s3=self.est.accel_psd_m2_s3 * a.accel_psd_factor,
                imu_latency_s=float(a.imu_latency_s),
            )
            model = Model(a.scene)
            self._runs = [
                _run(model, est, rec, _corrected(rec.data, a, i, self.config))
                for i, rec in enumerate(self.recs)
            ]
            self._key = key
            self.simulations += 1
        return self._runs

    def errors(self, theta) -> list:
        """The IMU's innovations (measured less predicted) per recording, shape (k_i, 9):
        rate (rad/s), specific force (m/s^2), attitude (rotation vector, world axes, rad)."""
        return [imu_innovations(run) for run, _ in self.runs(theta)]

    def residuals(self, theta) -> tuple[np.ndarray, list[str]]:
        """The residuals of ``theta`` (every innovation of the runs in order, whitened, then
        the square root of its spread: half their squares sum to the negative
        log-likelihood, up to a constant), and why runs broke."""
        runs = self.runs(theta)
        fused = [r for run, _ in runs for r in run]  # none where every run broke at once
        w = np.concatenate([_likelihood_terms(r) for r in fused]) if fused else np.empty(0)
        if self._spreads is None and fused:
            self._spreads = np.concatenate([_spread_entry(r) for r in fused])
        broke = [why for _, why in runs if why] + ([] if np.all(np.isfinite(w)) else ["NaN"])
        return w, broke

    def residual_variance(self, r: np.ndarray, p: int) -> float:
        """The noise variance of the whitened innovations among the residuals ``r`` (the
        spreads' square roots are no noise)."""
        w = r[~self._spreads]  # walled residuals keep the first run's length
        return float(w @ w) / max(len(w) - p, 1)

    def __call__(self, theta) -> np.ndarray:
        w, broke = self.residuals(theta)
        return self._walled(theta, w, _what_broke(broke))

    def batch(self, thetas) -> list:
        """The residuals of several parameter vectors, in order."""
        if self.workers <= 1 or self._length is None:
            return [self(t) for t in thetas]
        if self._pool is None:
            self._pool = _Workers(self)
        outs = self._pool.map(thetas)
        self.simulations += len(outs)
        return [
            self._walled(t, w, _what_broke(broke))
            for t, (w, broke) in zip(thetas, outs, strict=True)
        ]

    def close(self) -> None:
        """End the worker processes, if any."""
        if self._pool is not None:
            self._pool.close()
            self._pool = None


class _Workers:
    """``problem.workers`` processes, each with its own copy of ``problem``.

    The processes are spawned (a fresh interpreter: no thread of this one forked) and read the
    problem from a file: a spawned process imports the caller's main script first, and where
    that has no ``if __name__ == "__main__":`` guard it dies at start-up, which
    ``ProcessPoolExecutor`` reports as a broken pool only when the arguments it sends at
    start-up are small: with the recordings among them it waits forever (CPython 3.11)."""

    def __init__(self, problem: FilterProblem):
        fd, self.path = tempfile.mkstemp(prefix="gyrotens-filter-fit-", suffix=".pickle")
        with os.fdopen(fd, "wb") as f:
            parts = (problem.scene, problem.config, problem.est, problem.params, problem.recs)
            pickle.dump(parts, f)
        self.pool = ProcessPoolExecutor(
            problem.workers, get_context("spawn"), initializer=_start_worker, initargs=(self.path,)
        )

    def map(self, thetas) -> list:
        futures = []
        try:
            with _interrupts_held():  # the processes start here, on the first submissions
                futures = [self.pool.submit(_worker_residuals, t) for t in thetas]
            return [f.result() for f in futures]
        except BrokenProcessPool:
            raise FilterFitError(
                "a worker process of the filter fit ended abruptly; a script that fits with "
                "workers > 1 needs its top level under 'if __name__ == \"__main__\":' "
                "(processes are spawned), else fit with workers=1"
            ) from None
        finally:
            for f in futures:
                f.cancel()  # an interrupted batch is not finished

    def close(self) -> None:
        try:
            self.pool.shutdown(cancel_futures=True)  # an interrupted batch is not finished
        finally:
            os.unlink(self.path)


_worker_problem: FilterProblem | None = None
"""A worker process's copy of the problem (:class:`_Workers`)."""


@contextmanager
def _interrupts_held():
    """Ctrl-C held back within the block and raised when it ends.

    Ctrl-C reaches the whole process group: the parent's interrupt shuts the pool down, and a
    worker's own would print its traceback and break the pool under it. SIGINT is blocked in
    this thread, so that a process started within the block inherits the blocked signal from
    its first instruction (the mask survives the spawn's exec), before its imports, which take
    seconds on a slow machine, and keeps it: the pool's shutdown ends it. The mask is this
    thread's only: another thread of the process may take the signal, and Python then runs
    the handler in the main thread, within the block, where a KeyboardInterrupt halfway
    through starting a process left it reading a cut-off start-up message (its EOFError
    traceback on the terminal). So in the main thread the handler only notes the interrupt, and
    the block's end raises it; an ignored one would be lost. The resource tracker unblocks
    SIGINT when it starts, so it is started before the block."""
    resource_tracker.ensure_running()
    noted = []
    main = threading.current_thread() is threading.main_thread()
    handler = signal.signal(signal.SIGINT, lambda *_: noted.append(1)) if main else None
    signals = {signal.SIGINT}
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, signals)
    try:
        yield
    finally:
        if signal.SIGINT not in previous:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, signals)  # a pending one: noted now
        if main:
            signal.signal(signal.SIGINT, handler)
        if noted:
            raise KeyboardInterrupt


def _start_worker(path: str) -> None:
    global _worker_problem
    with open(path, "rb") as f:
        _worker_problem = FilterProblem(*pickle.load(f))


def _worker_residuals(theta):
    return _worker_problem.residuals(theta)


def usable_cores() -> int:
    """The cores this process may run on (all of them where the system does not say, as on
    macOS and Windows): the default of the fit's ``workers``."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _likelihood_terms(r) -> np.ndarray:
    """An innovation's residuals: whitened, and the square root of its spread (rounding can
    take a spread of zero a hair below it)."""
    return np.append(r.whitened, np.sqrt(max(r.spread, 0.0)))


def _spread_entry(r) -> np.ndarray:
    """Where :func:`_likelihood_terms` of ``r`` puts its spread."""
    return np.append(np.zeros(len(r.whitened), bool), True)


def _what_broke(broke: list[str]) -> str:
    """Why the filter runs broke, for :meth:`FilterProblem._walled` ("": none did)."""
    return f"the filter broke ({'; '.join(broke)})" if broke else ""


def _corrected(data: dict, a, k: int, config: RigConfig) -> dict:
    """The streams of recording ``k`` as the rig of ``a`` (:func:`.params.apply`) would have
    logged them without its biases and with its servos' zeros: the biases taken off the
    IMU's readings, the zero offsets added to the wound strings' reported and commanded
    lengths."""
    out = dict(data)
    imu = data[streams.IMU].copy()
    biases = (a.gyro_bias_rad_s[k], a.accel_bias_m_s2[k])
    for cols, bias in zip((streams.IMU_RATE, streams.IMU_ACCEL), biases, strict=True):
        for c, b in zip(cols, bias, strict=True):
            imu[c] -= b
    out[streams.IMU] = imu
    strings = [s.string for s in config.servos.servo if s.string]
    for name, column in ((streams.SERVOS, streams.servo_length_column),
                         (streams.COMMAND, streams.rest_column),
                         (streams.SERVO_GOALS, streams.rest_column)):  # fmt: skip
        if name in data:
            rows = data[name].copy()
            for s, offset in zip(strings, a.offsets_m, strict=True):
                if column(s) in rows.dtype.names:
                    rows[column(s)] += offset
            out[name] = rows
    return out


def turned_s(rec: FilterRecording, angle_rad: float) -> float | None:
    """Seconds from the recording's first IMU sample to the first whose reported attitude has
    turned further than ``angle_rad`` from that sample's; None if none has."""
    imu = rec.data[streams.IMU]
    R = rotation_zyx(imu["roll_rad"], imu["pitch_rad"], imu["yaw_rad"])  # (3, 3, k)
    beyond = np.flatnonzero(turn_from_first(np.moveaxis(R, -1, 0)) > angle_rad)
    return float(imu["t_s"][beyond[0]] - imu["t_s"][0]) if beyond.size else None


def roll_over_warning(rec: FilterRecording) -> str | None:
    """What to say of a recording whose window runs past the roll-over (:data:`ROLLED_OVER_RAD`),
    with the ``--until`` that ends it where the sensor has turned :data:`SUGGESTED_TURN_RAD`;
    None for a window that stays short of it."""
    over = turned_s(rec, ROLLED_OVER_RAD)
    if over is None:
        return None
    until = turned_s(rec, SUGGESTED_TURN_RAD)
    return (
        f"{rec.name}: the IMU turns {np.degrees(ROLLED_OVER_RAD):.0f} degrees from its start "
        f"{over:.2f} s into the fitted window: past the D-bar's roll-over the filter fit breaks "
        f"or lands wrong (docs/identification.md); --until {np.floor(10 * until) / 10:.1f} "
        f"ends the window where it has turned {np.degrees(SUGGESTED_TURN_RAD):.0f} degrees"
    )


def _run(model: Model, est: EstimatorConfig, rec: FilterRecording, data: dict):
    """The filter of ``model`` over ``data``: every :class:`~gyrohost.estimator.fusion.
    Innovation` in fusion order up to where it broke, and why it broke (None: it did not)."""
    ekf, samples = started(model, est, data)
    out = []
    ekf.log = out.append
    # Far from the optimum the filter can diverge: the break is counted, walled off and named
    # in the status line, and the overflow warnings on its way would bury the progress bar.
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", LinAlgWarning)
        try:
            sample_feed.run(ekf, samples)
        except EstimatorError as exc:
            return out, f"{rec.name}: {exc}"
    return out, None


def imu_innovations(run: list) -> np.ndarray:
    """The IMU's innovations of one run (:func:`_run`), shape (k, 9): rate, force, angles."""
    parts = [np.array([r.innovation for r in run if r.source == s]) for s in IMU_SOURCES]
    return np.column_stack(parts)


def fit(
    scene: Scene,
    config: RigConfig,
    est: EstimatorConfig,
    params: list[Param],
    recs: list,
    progress: Callable[[int, float], None] | None = None,
    max_nfev: int = 40,
    workers: int | None = 1,
    line: tuple[int, float] | None = None,
) -> output_fit.FitResult:
    """Fit ``params`` to the recordings ``recs`` (:class:`FilterRecording`) by the filter's
    prediction error; ``progress(runs, cost)`` after every evaluation; the Jacobians' columns
    and the profiles' samples in ``workers`` processes (None: :func:`usable_cores`). The result
    is the output-error fit's, its residuals the IMU's innovations (:data:`STREAMS`).

    ``line`` (index, sigma): the fit starts from the smooth minimum of the likelihood along
    that parameter within +-3 sigma of its nominal (:func:`.profile.line_start`)."""
    lower = np.array([p.lower for p in params])
    steps = [p.step for p in params]
    workers = usable_cores() if workers is None else workers
    problem = FilterProblem(scene, config, est, params, recs, workers)
    solve = output_fit.solver(params, progress, max_nfev, output_fit.SEGMENTED_FTOL, True)
    try:
        initial = problem.errors(np.zeros(len(params)))
        start, samples = np.zeros(len(params)), []
        if line is not None:
            start, samples = profile.line_start(problem, start, *line)
        sol, strings = profile.strings_valley(solve, problem, solve(problem, start), lower)
        final = problem.errors(sol.x)
        sigma, corr, unresolved, separable, combos, valley, _ = output_fit.statistics(
            problem, sol, lower, steps
        )
    finally:
        problem.close()
    rms = {
        name: (output_fit.stream_rms(initial, cols), output_fit.stream_rms(final, cols))
        for name, cols in STREAMS.items()
    }
    return output_fit.FitResult(
        params, sol.x, sigma, corr, unresolved, separable, combos, valley, final, initial, rms,
        float(sol.cost), int(sol.nfev), _status(sol.message, problem), scene, problem.servo_lag_s,
        strings_valley=[(k, float(c)) for k, _, c in strings], channels=CHANNELS, streams=STREAMS,
        residual_variance=problem.residual_variance(sol.fun, len(params)),
        start_line=None if line is None else (params[line[0]].name, start[line[0]], samples),
    )  # fmt: skip


def _status(message: str, problem: FilterProblem) -> str:
    """The optimiser's message, and how often the filter broke on the way (the first time)."""
    if not problem.failures:
        return message
    n = len(problem.failures)
    return (
        f"{message}; {n} of {problem.simulations} filter runs broke, first: {problem.failures[0]}"
    )
