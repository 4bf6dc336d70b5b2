"""Synthetic truth and sensor streams for testing the filter without the rig.

The truth is the reference model (:class:`gyrotensegrity.Stepper`, RK4 with 1 ms substeps, the
scene's schedules) plus, optionally, the process noise the filter assumes: at every sample a
random change of positions and velocities with the covariance of white node accelerations of
density ``accel_psd_m2_s3``, after which the state is projected back onto the constraints.
Sensor streams are the truth seen through :class:`~.imu_model.ImuGeometry` plus white noise of the
configured standard deviations and a gyro bias drawn once; they come out as structured arrays
with the columns of :mod:`.streams`, exactly like streams read from a run log.
"""

from dataclasses import dataclass

import numpy as np

from gyrohost.estimator import streams as cols
from gyrohost.estimator.imu_model import ImuGeometry, euler_zyx
from gyrohost.estimator.layout import from_model_state
from gyrohost.geometry import wrap_angle
from gyrotensegrity import Stepper, evaluate
from gyrotensegrity.projection import project


@dataclass(frozen=True)
class TruthRun:
    """Truth sampled every ``dt_s``.

    t_s (k,) s; x (k, n) filter states (true rest lengths and gyro bias included); R_ws
    (k, 3, 3) sensor axes; omega_s (k, 3) rad/s; specific_force (k, 3) m/s^2; rest_length
    (k, alpha) m, what the servos reached; command (k, alpha) m, the commanded rest lengths.
    """

    t_s: np.ndarray
    x: np.ndarray
    R_ws: np.ndarray
    omega_s: np.ndarray
    specific_force: np.ndarray
    rest_length: np.ndarray
    command: np.ndarray


def simulate_truth(
    model, config, duration_s, seed, dt_s=0.01, substep_s=1e-3, accel_psd_m2_s3=None
):
    """Run the truth for ``duration_s`` seconds; ``seed`` draws the bias and disturbances.

    The scene's rest-length schedule is the command; the servos follow it with the first-order
    lag ``config.servo_lag_s`` (as the rig's truth with ``servo_lag_s``), the model runs on what
    they reach. ``accel_psd_m2_s3`` is the density of the disturbance (default: the filter's
    own, ``config.accel_psd_m2_s3``; 0 for none).
    """
    psd = config.accel_psd_m2_s3 if accel_psd_m2_s3 is None else accel_psd_m2_s3
    rng = np.random.default_rng(seed)
    geo = ImuGeometry(model, config)
    bias = rng.normal(0.0, config.init_gyro_bias_std_rad_s, 3)
    stepper = Stepper(model, max_dt=substep_s)
    L = model.layout
    chol = np.linalg.cholesky(np.array([[dt_s**3 / 3, dt_s**2 / 2], [dt_s**2 / 2, dt_s]]))
    chol *= np.sqrt(psd)
    n_sub = max(1, int(np.ceil(dt_s / substep_s - 1e-9)))
    h = dt_s / n_sub
    decay, decay_mid = np.exp(-h / config.servo_lag_s), np.exp(-0.5 * h / config.servo_lag_s)
    u = model.input_at(0.0)
    rest = u[: model.alpha].copy()
    command = u
    rows = []
    for k in range(int(round(duration_s / dt_s)) + 1):
        if k:
            for _ in range(n_sub):  # servo lag integrated exactly, the model sees mid-substep
                cmd = command[: model.alpha]
                u[: model.alpha] = cmd + (rest - cmd) * decay_mid
                stepper.step(h, u)
                rest = cmd + (rest - cmd) * decay
            if psd > 0.0:
                w = chol @ rng.standard_normal((2, 3 * model.m))
                stepper.x[L.q] += w[0]
                stepper.x[L.q_dot] += w[1]
                stepper.x = project(model, stepper.x)
        command = model.input_at(stepper.t)  # held until the next sample
        u[: model.alpha] = rest
        ev = evaluate(stepper.t, stepper.x, u, model)
        R, omega = geo.frame(ev.N[None], ev.N_dot[None])
        f = geo.specific_force(R, ev.N_ddot[None])
        x = from_model_state(model, stepper.x, u, bias)
        rows.append((stepper.t, x, R[0], omega[0], f[0], rest.copy(), command[: model.alpha]))
    t, x, R, om, f, rest, cmd = (np.array(v) for v in zip(*rows, strict=True))
    return TruthRun(t, x, R, om, f, rest, cmd)


def _structured(columns, data):
    out = np.empty(len(data), dtype=[(c, "f8") for c in columns])
    for j, c in enumerate(columns):
        out[c] = data[:, j]
    return out


def sensor_streams(model, config, truth: TruthRun, seed, servo_every=5, servo_noise_m=2e-4):
    """IMU and wheel samples at every truth sample, servo reads every ``servo_every`` samples.

    The servos read the rest lengths they reached plus white noise ``servo_noise_m`` (m).

    Returns
    -------
    dict of structured arrays: ``imu``, ``wheels``, ``servos``, ``command`` (columns of
    :mod:`.streams`); the servos read every string.
    """
    rng = np.random.default_rng(seed + 1_000_003)
    c = config
    k = len(truth.t_s)
    L_bias = slice(truth.x.shape[1] - 3, truth.x.shape[1])
    n_w = len(model.wheel_bars)
    rate = truth.omega_s + truth.x[:, L_bias] + rng.normal(0, c.imu_rate_std_rad_s, (k, 3))
    accel = truth.specific_force + rng.normal(0, c.imu_accel_std_m_s2, (k, 3))
    angle = wrap_angle(euler_zyx(truth.R_ws) + rng.normal(0, c.imu_angle_std_rad, (k, 3)))
    omega_w = truth.x[:, 6 * model.m : 6 * model.m + n_w]  # the wheels are not commanded here
    wheels = omega_w + rng.normal(0, c.wheel_speed_std_rad_s, omega_w.shape)
    idx = np.arange(0, k, servo_every)
    lengths = truth.rest_length[idx] + rng.normal(0, servo_noise_m, (len(idx), model.alpha))
    names = [s.name for s in model.scene.strings]
    t = truth.t_s[:, None]
    return {
        cols.IMU: _structured(cols.imu_columns(), np.hstack([t, rate, accel, angle])),
        cols.WHEELS: _structured(cols.wheels_columns(n_w), np.hstack([t, wheels])),
        cols.SERVOS: _structured(cols.servos_columns(names), np.hstack([t[idx], lengths])),
        cols.COMMAND: _structured(
            cols.command_columns(names, n_w), np.hstack([t, truth.command, omega_w])
        ),
    }


def write_log(folder, data, scene_path, meta=None):
    """Write synthetic streams ``data`` as a run log (what the run loop would record)."""
    from gyrohost.run.log import RunLog

    with RunLog(folder, {"scene": str(scene_path), **(meta or {})}) as log:
        for name, rows in data.items():
            stream = log.stream(name, rows.dtype.names)
            for row in rows:
                stream.write(*row.tolist())
