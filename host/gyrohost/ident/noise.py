"""The sensors' noise, measured where a run log holds the rig still: the figures of the
estimator's noise keys (``imu_rate_std_rad_s`` and the others of :data:`KEYS`), which the lab-rig
template gives from datasheets and which the filter fit weighs its innovations by
(:mod:`.filter_fit`: the likelihood's ``R``).

The still window of a log starts with its ``lead_in`` phase (the wheels have reached their
speeds, the structure sits where the scene starts it) and ends at the first command that differs
from the one in effect then (the identification schedule's first second is a rest, the paper's
pulls at once), or where the run winds down. Within it every channel is detrended by a straight
line in time (the gyro's bias drift, the fused yaw's creep, a slow turn of the D-bar's roll
mode) and its scatter about the line is the noise: pooled over a sensor's axes (the keys are one
figure per sensor), with the chi-square 95 % interval of the pooled degrees of freedom.

A channel that reads still as one count scatters by no more than its quantisation; the figure
to configure is never below one count over ``sqrt(12)``, the spread of the rounding, because a
zero variance would let one sample pin the filter's state. The accelerometer's bias, which a
still window cannot tell from the mounting's tilt against gravity (``gyrotens identify`` fits
the two together), is a state of the filter where ``init_accel_bias_std_m_s2`` gives it a
prior, and the figure is the white noise alone; a filter without that state folds the bias
left after the device's own calibration (``FF AA 67``) into the figure
(``sqrt(white^2 + bias^2)``).

The servos' reads are left out: a held servo reads the count it holds at, and
``servo_length_std_m`` with ``servo_time_std_s`` carry what they do while moving
(docs/estimator-noise.md#the-servos).
"""

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.stats import chi2

from gyrohost.estimator import streams
from gyrohost.estimator.config import EstimatorConfig, imu_wire_counts
from gyrohost.ident.errors import IdentDataError
from gyrohost.ident.logs import FIRST_PHASE, phase_starts
from gyrohost.run.errors import LogError
from gyrohost.run.log import read_streams

START_PHASE = FIRST_PHASE
END_PHASES = ("settle", "rampdown")
"""Phases whose start ends the still window at the latest (the run winding down)."""
MIN_SAMPLES = 20
"""Fewer samples of a stream in the still window than this: no figure for it (with 20 the 95 %
interval of one axis spans -30 to +50 %)."""
REST_TOLERANCE_M = 1e-7
WHEEL_TOLERANCE_RAD_S = 1e-6
"""A command differs from the one in effect when a rest length or a wheel speed moves by more
than these (a schedule's own rounding stays far below them)."""
CORRELATED = 0.5
"""A lag-1 autocorrelation above this marks a sensor whose samples are not independent (a
low-pass in the device): its interval is then too narrow, and the filter's white noise of that
figure overconfident at its rate."""


@dataclass(frozen=True)
class NoiseFigure:
    """One estimator key measured.

    Attributes
    ----------
    key : str
        The estimator key (``imu_rate_std_rad_s``).
    unit : str
    std : float
        The pooled scatter about each channel's line, unit.
    channels : dict of str to float
        Each channel's own scatter, unit.
    dof : int
        Degrees of freedom pooled (samples less two per channel).
    interval95 : (float, float)
        Chi-square 95 % interval of ``std``, unit (for independent samples).
    lag1 : float
        Mean lag-1 autocorrelation of the detrended channels.
    floor : float
        One count of the wire over ``sqrt(12)``, unit: the least figure to configure.
    configured : float
        The configuration's figure, unit.
    bias : float
        A bias the figure folds in (the accelerometer's; 0 for the others), unit.
    """

    key: str
    unit: str
    std: float
    channels: dict
    dof: int
    interval95: tuple[float, float]
    lag1: float
    floor: float
    configured: float
    bias: float = 0.0

    @property
    def suggested(self) -> float:
        """The figure to configure: the measured one, at least :attr:`floor`, with
        :attr:`bias` folded in."""
        return math.hypot(max(self.std, self.floor), self.bias)

    @property
    def correlated(self) -> bool:
        return self.lag1 > CORRELATED


def still_window(folder: Path, data: dict) -> tuple[float, float]:
    """Host times (s) where the still window of the log ``folder`` (its streams ``data``, an
    ``events`` and a ``command`` stream among them) starts and ends.

    Raises
    ------
    IdentDataError
        The log has no ``lead_in`` phase.
    """
    starts = phase_starts(data["events"])
    if START_PHASE not in starts:
        raise IdentDataError(
            f"{folder}: no '{START_PHASE}' phase in its events: not a gyrotens run log, or the "
            "run ended before its wheels were spun up"
        )
    t0 = starts[START_PHASE]
    t1 = min([starts[p] for p in END_PHASES if p in starts and starts[p] > t0], default=np.inf)
    command = data.get(streams.COMMAND)
    if command is not None and len(command):
        t1 = min(t1, _first_change_s(command, t0))
    return t0, t1


def _first_change_s(command: np.ndarray, t0: float) -> float:
    """Time (s) of the first command after ``t0`` that differs from the one in effect at
    ``t0`` (inf: none does)."""
    columns = [c for c in command.dtype.names if c != "t_s"]
    held = max(np.searchsorted(command["t_s"], t0, side="right") - 1, 0)
    values = np.column_stack([command[c] for c in columns])
    tolerance = np.array([REST_TOLERANCE_M if c.endswith("_rest_m") else WHEEL_TOLERANCE_RAD_S
                          for c in columns])  # fmt: skip
    later = np.arange(len(command)) > held
    moved = later & np.any(np.abs(values - values[held]) > tolerance, axis=1)
    return float(command["t_s"][np.argmax(moved)]) if moved.any() else np.inf


def detrended(t_s: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``values`` (k,) less their least-squares line in ``t_s`` (k,) s."""
    return values - np.polyval(np.polyfit(t_s - t_s[0], values, 1), t_s - t_s[0])


def lag1(residual: np.ndarray) -> float:
    """Lag-1 autocorrelation of a zero-mean series (0 for a constant one)."""
    power = float(residual @ residual)
    return float(residual[1:] @ residual[:-1]) / power if power > 0.0 else 0.0


def figure(key, unit, pieces, floor, configured, bias=0.0) -> NoiseFigure:
    """The :class:`NoiseFigure` of ``key`` from ``pieces``: (channel name, times (k,) s,
    values (k,)) of every channel in every still window."""
    scatter, dofs, lags = {}, {}, []
    for name, t, v in pieces:
        r = detrended(t, v)
        scatter[name] = scatter.get(name, 0.0) + float(r @ r)
        dofs[name] = dofs.get(name, 0) + len(r) - 2
        lags.append(lag1(r))
    dof = sum(dofs.values())
    std = math.sqrt(sum(scatter.values()) / dof)
    interval = tuple(std * math.sqrt(dof / chi2.ppf(q, dof)) for q in (0.975, 0.025))
    channels = {n: math.sqrt(scatter[n] / dofs[n]) for n in scatter}
    lag = float(np.mean(lags))
    return NoiseFigure(key, unit, std, channels, dof, interval, lag, floor, configured, bias)


SENSORS = (
    ("imu_rate_std_rad_s", "rad/s", streams.IMU, streams.IMU_RATE),
    ("imu_accel_std_m_s2", "m/s^2", streams.IMU, streams.IMU_ACCEL),
    ("imu_angle_std_rad", "rad", streams.IMU, streams.IMU_ANGLE),
    ("wheel_speed_std_rad_s", "rad/s", streams.WHEELS, tuple(streams.wheel_speed_columns())),
)
"""(estimator key, unit, stream, columns) of every figure :func:`measure` takes."""
KEYS = tuple(key for key, *_ in SENSORS)
"""The estimator keys :func:`measure` gives figures of (where the logs hold their streams)."""


def _floors(est: EstimatorConfig) -> dict:
    """Key -> one count of its wire over ``sqrt(12)``, for every key of :data:`KEYS`."""
    counts = (*imu_wire_counts(), est.wheel_resolution_rad_s)
    return {key: c / math.sqrt(12.0) for key, c in zip(KEYS, counts, strict=True)}


NOTES = {
    "wheel_speed_std_rad_s": "the telemetry's scatter with the wheels' own wander (the speed "
    "loop's error, which the filter carries as the wheel states' walk): an upper bound",
}
"""What a figure holds beyond the sensor's white noise."""


def measure(folders, est: EstimatorConfig, accel_bias_m_s2: float) -> tuple[list, list]:
    """The noise figures of the still windows of the run logs ``folders``.

    Parameters
    ----------
    folders : list of path
    est : EstimatorConfig
        The estimator of the rig the logs were recorded on (the configured figures, the
        wheels' wire step).
    accel_bias_m_s2 : float
        The accelerometer's bias (per axis, 1-sigma) its figure folds in, m/s^2, where the
        estimator has no state of it (``init_accel_bias_std_m_s2 = 0``); with one, the
        figure is the white noise alone.

    Returns
    -------
    figures : list of NoiseFigure
        One per key of :data:`KEYS` whose stream the windows hold at least
        :data:`MIN_SAMPLES` of.
    windows : list of (str, float, float, int)
        Per log: its folder, the window's start and length (s), its IMU samples.

    Raises
    ------
    IdentDataError
        A log cannot be read, has no still window, or holds fewer than :data:`MIN_SAMPLES`
        IMU samples in it (naming the log and the window).
    """
    pieces = {key: [] for key in KEYS}
    windows = []
    for folder in map(Path, folders):
        data = _read(folder)
        t0, t1 = still_window(folder, data)
        inside = {k: v[(v["t_s"] >= t0) & (v["t_s"] < t1)] for k, v in data.items()}
        n_imu = len(inside[streams.IMU])
        if n_imu < MIN_SAMPLES:
            raise IdentDataError(
                f"{folder}: {n_imu} IMU samples where the rig is still ({t1 - t0:.2f} s from "
                f"'{START_PHASE}' to the first command that moves it), at least {MIN_SAMPLES} "
                "needed: record a run whose schedule starts with a rest (--schedule identify)"
            )
        windows.append((str(folder), t0, t1 - t0, n_imu))
        for key, _, stream, columns in SENSORS:
            rows = inside.get(stream)
            if rows is None or len(rows) < MIN_SAMPLES:
                continue
            for c in (c for c in columns if c in rows.dtype.names):
                v = np.unwrap(rows[c]) if c in streams.IMU_ANGLE else rows[c]
                pieces[key].append((c, rows["t_s"], np.asarray(v, float)))
    folded = accel_bias_m_s2 if est.init_accel_bias_std_m_s2 == 0.0 else 0.0
    floors, biases = _floors(est), {"imu_accel_std_m_s2": folded}
    figures = [
        figure(key, unit, pieces[key], floors[key], float(getattr(est, key)), biases.get(key, 0.0))
        for key, unit, *_ in SENSORS
        if pieces[key]
    ]
    return figures, windows


def _read(folder: Path) -> dict:
    names = ("events", streams.IMU, streams.WHEELS, streams.SERVOS, streams.COMMAND)
    try:
        data = read_streams(folder, names, warn=lambda _: None)
    except LogError as exc:
        raise IdentDataError(str(exc)) from None
    for name in ("events", streams.IMU):
        if name not in data:
            raise IdentDataError(f"{folder}: stream '{name}' missing or unreadable")
    return data


def report_lines(figures: list, windows: list) -> list[str]:
    """The figures as a table (measured, its interval, each channel, the configured figure),
    the windows they come from, and what to paste into the configuration's ``[estimator]``."""
    out = [f"{name}: still {length:.2f} s from {t0:.2f} s, {n} IMU samples"
           for name, t0, length, n in windows]  # fmt: skip
    out.append(
        f"{'key':24s} {'measured':>10s} {'95 % interval':>23s} {'configured':>10s}  channels"
    )
    for f in figures:
        low, high = f.interval95
        channels = ", ".join(f"{c} {v:.3g}" for c, v in f.channels.items())
        out.append(f"{f.key:24s} {f.std:10.3g} [{low:10.3g}, {high:10.3g}] {f.configured:10.3g}"
                   f"  {channels} ({f.unit})")  # fmt: skip
        if f.key in NOTES:
            out.append(f"  {f.key}: {NOTES[f.key]}")
        if f.correlated and f.std >= f.floor:  # a count's round-off is no low-pass
            out.append(f"  {f.key}: samples correlated (lag-1 {f.lag1:.2f}): a low-pass in the "
                       "device; the interval is too narrow")  # fmt: skip
        if f.std < f.floor:
            out.append(f"  {f.key}: below its quantisation; configure one count / sqrt(12)")
    out += ["", "[estimator]   # measured by gyrotens noise (docs/estimator.md)"]
    for f in figures:
        why = f"  # white {f.std:.3g} with a bias of {f.bias:.3g} folded in" if f.bias else ""
        out.append(f"{f.key} = {f.suggested:.3g}{why}")
    return out
