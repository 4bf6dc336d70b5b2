"""The real-time run loop's effects on the filter's consistency, one at a time, on the simulated
clock (deterministic: every delay is drawn from the run's seed).

The study ``python -m studies.estimator_effects`` scores each case over seeds.

The in-process SIL (:mod:`.scoring`) hands the filter every sample at its true time, the
wheel board's latest frame at every IMU sample. The run loop (``gyrohost.run``) differs in the
ways :class:`Effects` names; each can be switched on alone and the runs scored as the SIL
scores them (NEES over the full state at the filter's time, against the truth interpolated to
it). Delays: a sample arrives ``0.5 ms + Exp(delay)`` after it was taken (serial transfer, the
reader thread's wake-up); the loop's ticks are ``10 ms k + Exp(late)`` (its measured lateness:
p99 a few ms on an idle machine, tens of ms under load).
"""

from dataclasses import dataclass, fields, replace

import numpy as np

from gyrohost.estimator import sample_feed, streams
from gyrohost.estimator.config import EXACT_IMU_TIMES, config_from_dict
from gyrohost.estimator.consistency import sample_initial
from gyrohost.estimator.ekf import TensegrityEKF
from gyrohost.sil.emulator_keys import emulator_keys
from gyrohost.sil.montecarlo import START_SEED_OFFSET, sampled_truth, score_run
from gyrohost.sil.scoring import RIG_MODEL_KEYS, rig_model_run

TICK_S = 0.01  # the run loop's period, s
MIN_DELAY_S = 5e-4  # the smallest arrival delay, s
MAX_FUSED_PER_TICK = 4  # the run loop's default (gyrohost.run.settings)
# A command sent at a late tick moves the truth's servos from its send; the filter, whose clock
# the IMU's regridded samples set, cannot place each such tick sample by sample: the scatter
# (about 1 ms at Exp(1 ms) lateness) is carried by the rest-length walk: at the manoeuvre's
# 0.03-0.1 m/s a command switched 1 ms off moves the rest length by v 10 ms 1 ms / servo lag
# each 10 ms tick, a walk of 1e-8 to 1e-7 m^2/s at the 13 ms lag (docs/estimator.md)
LATE_COMMAND_REST_PSD_M2_S = 5e-8
SERVO_PERIOD_S = 0.04  # the servo worker's read period (gyrohost.run.settings: 25 Hz), s
# how long after the servos sample a read it reaches the host (the end of the bulk read): a
# read stamped on arrival lines up with the real-time rig's truth best 6-10 ms earlier
SERVO_READ_DELAY_S = 8e-3
# The newest telemetry frame at each late tick is 8 to 12 ms after the last (500 Hz frames):
# from one such sample to the next the noise is white (lag one +0.05, where the SIL's exact
# 10 ms has -0.48), but the encoder's counts still telescope in long means (a mean of 50 keeps
# 0.42-0.71 of white noise's variance, 0.56 on average): an MA(1) whose long means keep that,
# (1 + theta)^2 / (1 + theta^2) = 0.56 at theta -0.23 (white left the wheel block at 2.65 of 4)
TICKED_WHEEL_KEYS = {"wheel_noise_ma1": -0.25}
# the truth is recorded this long past the streams: the late ticks predict the filter past the
# last sample, where the scoring needs the truth
TRUTH_MARGIN_S = 3 * TICK_S


@dataclass(frozen=True)
class Effects:
    """Which of the run loop's ways differ from the in-process SIL (all False: the SIL)."""

    imu_arrival: bool = False  # IMU samples stamped on arrival
    imu_regrid: bool = False  # ...and put back on the IMU's 10 ms grid (sample_feed.regular_times)
    wheel_frames: bool = False  # every telemetry frame, stamped on arrival, 4 newest per tick
    wheel_clock: bool = False  # ...stamped by the board's clock, the newest one per tick
    late_ticks: bool = False  # ticks late as the loop's: commands sent then, the filter told
    command_at_last_sample: bool = False  # ...told at the newest sample fused before it
    rig_noise: bool = False  # the filter's noise keys of the real-time rig (no RIG_MODEL_KEYS)
    servo_cycle: bool = False  # goals reach the servos at the worker's next read, not at once
    servo_read_late: bool = False  # servo reads reach the host SERVO_READ_DELAY_S after sampling
    servo_read_arrival: bool = False  # ...and are stamped then (else when sampled)

    def label(self) -> str:
        on = [f.name for f in fields(self) if getattr(self, f.name)]
        return " + ".join(on) or "none (the SIL)"


def _with_times(arr, t_s):
    out = arr.copy()
    out["t_s"] = t_s
    return out


def _wheel_frames(frames, n_w):
    arr = np.empty(len(frames), dtype=[(c, "f8") for c in streams.wheels_columns(n_w)])
    arr["t_s"] = frames[:, 0]
    for i, c in enumerate(streams.wheel_speed_columns(n_w)):
        arr[c] = frames[:, 1 + i]
    return arr


def loop_ticks(duration_s: float, effects: Effects, rng, late_s: float):
    """The run loop's tick times, s (10 ms apart, each late by Exp(``late_s``) if so said)."""
    ticks = np.arange(0.0, duration_s + 2 * TICK_S, TICK_S)
    return ticks + rng.exponential(late_s, len(ticks)) if effects.late_ticks else ticks


def loop_streams(data, frames, effects: Effects, rng, delay_s: float):
    """The streams as the run loop hands them to the filter.

    Returns
    -------
    data : dict of structured arrays, ``t_s`` the time the filter is told
    arrival_s : dict, stream -> ndarray, when each sample reaches the host, s
    """
    out, arrival = dict(data), {}
    imu_t = data[streams.IMU]["t_s"]
    for name in out:
        arrival[name] = out[name]["t_s"].copy()
    if effects.imu_arrival:
        arrival[streams.IMU] = imu_t + MIN_DELAY_S + rng.exponential(delay_s, len(imu_t))
        stamps = arrival[streams.IMU]
        if effects.imu_regrid:
            stamps = sample_feed.regular_times(stamps, TICK_S, 0.03)
        out[streams.IMU] = _with_times(data[streams.IMU], stamps)
    if effects.wheel_frames:
        w = _wheel_frames(frames, len(frames[0]) - 1)
        board_t = w["t_s"].copy()
        arrival[streams.WHEELS] = board_t + MIN_DELAY_S + rng.exponential(delay_s, len(w))
        stamps = arrival[streams.WHEELS]
        if effects.wheel_clock:  # the board's clock on the host's: the smallest delay so far
            stamps = board_t + np.minimum.accumulate(stamps - board_t)
        out[streams.WHEELS] = _with_times(w, stamps)
    if effects.servo_read_late:
        arrival[streams.SERVOS] = data[streams.SERVOS]["t_s"] + SERVO_READ_DELAY_S
        if effects.servo_read_arrival:
            out[streams.SERVOS] = _with_times(data[streams.SERVOS], arrival[streams.SERVOS])
    return out, arrival


def cut_streams(data, frames, duration_s: float):
    """The streams and telemetry frames of a run up to ``duration_s`` (the truth runs on)."""
    data = {name: arr[arr["t_s"] <= duration_s + 1e-9] for name, arr in data.items()}
    return data, frames[frames[:, 0] <= duration_s + 1e-9]


def servo_cycle_sends(ticks, duration_s: float, rng):
    """When the servo worker's reads (every ``SERVO_PERIOD_S``, phase from ``rng``) send the
    newest goal, s, and the tick that made each goal, s."""
    sends = np.arange(rng.uniform(0.0, SERVO_PERIOD_S), duration_s + SERVO_PERIOD_S, SERVO_PERIOD_S)
    made = np.searchsorted(ticks, sends, side="right") - 1
    return sends, ticks[np.maximum(made, 0)]


def commands_at(model, template, times_s):
    """Command stream rows (``template``'s columns) of the schedule at ``times_s``: what the
    loop tells the filter at its ticks."""
    out = np.repeat(template[:1], len(times_s))
    out["t_s"] = times_s
    rest = np.array([model.input_at(t)[: model.alpha] for t in times_s])
    for j, name in enumerate(template.dtype.names[1 : 1 + model.alpha]):
        out[name] = rest[:, j]
    return out


def ticked_feed(arrival, ticks, effects: Effects):
    """A ``feed`` for :func:`.montecarlo.score_run`: each tick drains what has arrived since
    the last and fuses the newest ``MAX_FUSED_PER_TICK`` of each stream (the newest wheel frame
    only with ``wheel_clock``) in the order of their stamps, as ``gyrohost.run.dispatch`` does;
    then the tick's command (``command_at_last_sample``: at the filter's time by then), and
    predicts to the tick (the loop writes its estimate there)."""

    def feed(ekf, data, on_step):
        prev = -np.inf
        for tick in ticks:
            part = {}
            for name, arr in data.items():
                idx = np.flatnonzero((arrival[name] > prev) & (arrival[name] <= tick))
                keep = 1 if name == streams.WHEELS and effects.wheel_clock else MAX_FUSED_PER_TICK
                idx = idx[np.argsort(arr["t_s"][idx], kind="stable")][-keep:]
                if idx.size:
                    part[name] = arr[idx]
            prev = tick
            command = part.pop(streams.COMMAND, None)
            if part:
                sample_feed.run(ekf, part, on_step)
            if command is not None:
                if effects.command_at_last_sample:
                    command = _with_times(command, np.full(len(command), max(ekf.t, 0.0)))
                sample_feed.run(ekf, {streams.COMMAND: command}, on_step)
            ekf.advance(max(tick, ekf.t))  # the loop's estimate at every tick

    return feed


def score_with_effects(
    config, seed, effects: Effects, duration_s=3.0, delay_s=2e-3, late_s=1e-3, overrides=None
):
    """One :func:`.scoring.rig_model_run` handed to the filter as ``effects`` say;
    ``overrides``: estimator keys on top of the case's."""
    rng = np.random.default_rng(seed + 9_000_011)
    ticks = loop_ticks(duration_s, effects, rng, late_s)
    sends, made = (
        servo_cycle_sends(ticks, duration_s, rng) if effects.servo_cycle else (ticks, None)
    )
    model, data, truth_x, truth_R, frames, dt_s = rig_model_run(
        config, seed, duration_s + TRUTH_MARGIN_S, sends, made
    )
    data, frames = cut_streams(data, frames, duration_s)
    if effects.servo_cycle:  # the filter is told each command at its tick
        data[streams.COMMAND] = commands_at(model, data[streams.COMMAND], ticks)
    fed, arrival = loop_streams(data, frames, effects, rng, delay_s)
    # the real-time rig's noise, the samples' own times (each delay of this harness is its own
    # and known: no uncertainty about them)
    keys = {**emulator_keys(config), **(EXACT_IMU_TIMES if effects.rig_noise else RIG_MODEL_KEYS)}
    if effects.imu_regrid:  # the grid's times lead the samples by the smallest delay
        keys["imu_latency_s"] = MIN_DELAY_S
    if effects.late_ticks:
        keys["rest_psd_m2_s"] = LATE_COMMAND_REST_PSD_M2_S
    if effects.wheel_frames:  # fitted to the newest frame at each tick (wheel_clock)
        keys.update(TICKED_WHEEL_KEYS)
    keys.update(overrides or {})
    est_cfg = config_from_dict(keys)
    ekf = TensegrityEKF(model, est_cfg)
    x0 = sample_initial(ekf, truth_x[0], np.random.default_rng(seed + START_SEED_OFFSET))
    ekf = TensegrityEKF(model, est_cfg, x0=x0)
    feed = ticked_feed(arrival, ticks, effects)
    return score_run(ekf, fed, sampled_truth(truth_x, truth_R, dt_s), feed=feed)


CASES = {
    "sil": Effects(),
    "imu-arrival": Effects(imu_arrival=True),
    "imu-regrid": Effects(imu_arrival=True, imu_regrid=True),
    "wheel-frames": Effects(wheel_frames=True),
    "wheel-clock": Effects(wheel_frames=True, wheel_clock=True),
    "late-ticks": Effects(late_ticks=True),
    "command-at-last-sample": Effects(late_ticks=True, command_at_last_sample=True),
    "rig-noise": Effects(rig_noise=True),
    "loop-before": Effects(  # the run loop before the fixes of docs/estimator.md
        imu_arrival=True,
        wheel_frames=True,
        late_ticks=True,
        command_at_last_sample=True,
        rig_noise=True,
        servo_cycle=True,
        servo_read_late=True,
        servo_read_arrival=True,
    ),
    "loop-fixed": Effects(
        imu_arrival=True,
        imu_regrid=True,
        wheel_frames=True,
        wheel_clock=True,
        late_ticks=True,
        servo_read_late=True,
    ),
}
CASES["loop-fixed-rig-noise"] = replace(CASES["loop-fixed"], rig_noise=True)
CASES["servo-cycle"] = replace(CASES["loop-fixed"], servo_cycle=True)
CASES["servo-read-arrival"] = replace(CASES["loop-fixed"], servo_read_arrival=True)
CASES["servo-before"] = replace(CASES["servo-read-arrival"], servo_cycle=True)
