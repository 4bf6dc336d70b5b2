"""The fit's attitude residual and the segments' anchor without Euler angles: the D-bar takes the
sensor's pitch through -90 degrees, where roll and yaw are singular."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyrohost.config import load_rig_config
from gyrohost.estimator.fuse_imu_angle import FLOOR, euler_rate_matrix
from gyrohost.geometry import euler_zyx, levelling_rotvec, rotation_zyx, turn_from_first
from gyrohost.ident.forward import tilt_error, tilt_std
from gyrohost.ident.shooting import anchored
from gyrohost.resources import shipped
from gyrohost.simrig.config import sim_config
from gyrohost.simrig.truth import Truth
from gyrotensegrity import load_scene

STD_RAD = 0.005  # the angles' noise in these tests


def _exp(rotvec):
    return Rotation.from_rotvec(rotvec).as_matrix()


def test_levelling_rotation_is_the_horizontal_rotation_that_tilted_the_up_direction():
    """``z`` tilted by ``exp(-d)`` (``d`` horizontal, up to 170 degrees) and turned about the
    vertical by ``a``: levelled by ``Rz(a) d``."""
    rng = np.random.default_rng(3)
    for _ in range(50):
        d = np.append(rng.uniform(-1.0, 1.0, 2), 0.0)
        d *= rng.uniform(0.0, np.radians(170.0)) / np.linalg.norm(d)
        Rz = _exp([0.0, 0.0, rng.uniform(-np.pi, np.pi)])
        up = Rz @ _exp(-d) @ [0.0, 0.0, 1.0]
        assert levelling_rotvec(up) == pytest.approx(Rz @ d, abs=1e-9)
    assert np.all(levelling_rotvec([0.0, 0.0, 1.0]) == 0.0)


@pytest.mark.parametrize("pitch_deg", [-90.0, -89.99, -60.0, 0.0, 89.0])
def test_tilt_error_is_the_horizontal_rotation_between_the_attitudes(pitch_deg):
    """Predicted ``exp(d) R_m`` against measured ``R_m`` (given by its angles as the IMU reports
    them): the residual is ``d`` in the measured world turned to zero yaw, whatever the split of
    roll and yaw at pitch -90; a turn of the prediction about the vertical leaves it alone."""
    R_m = rotation_zyx(0.7, np.radians(pitch_deg), -2.0)
    angles = euler_zyx(R_m)
    d = np.array([0.02, -0.03, 0.0])  # predicted less measured, world, rad
    for yaw_turn in (0.0, 1.3):
        R_p = _exp([0.0, 0.0, yaw_turn]) @ _exp(d) @ R_m
        got = tilt_error(R_p[None], angles[None, :2])[0]
        # the measured world at zero yaw: a turn about the vertical, even where the reported
        # roll and yaw do not give back R_m (pitch -90)
        W = rotation_zyx(angles[0], angles[1], 0.0) @ R_m.T
        assert W[2, 2] == pytest.approx(1.0, abs=1e-12)
        assert got == pytest.approx((W @ d)[:2], abs=1e-12)
        assert np.linalg.norm(got) == pytest.approx(np.linalg.norm(d), rel=1e-12)


def test_tilt_error_is_bounded_and_finite_for_any_attitudes():
    rng = np.random.default_rng(4)
    R_p = Rotation.random(2000, random_state=rng).as_matrix()
    angles = np.column_stack(
        [rng.uniform(-np.pi, np.pi, 2000), rng.uniform(-1, 1, 2000) * np.pi / 2]
    )
    angles[:100, 1] = -np.pi / 2  # exactly singular
    err = tilt_error(R_p, angles)
    assert np.all(np.isfinite(err))
    assert np.all(np.linalg.norm(err, axis=1) <= np.pi + 1e-12)


def _whitened_rms(roll, pitch):
    """RMS of :func:`tilt_error` over :func:`tilt_std` between an attitude and 20000 noisy
    reports of it (``STD_RAD`` on each angle, as the emulated IMU adds it, then reported as
    angles again: through -90 degrees pitch turns back and roll and yaw jump by pi), (2,)."""
    rng = np.random.default_rng(5)
    R_true = rotation_zyx(roll, pitch, 0.9)
    noisy = euler_zyx(R_true) + rng.normal(0.0, STD_RAD, (20000, 3))
    reported = np.array([euler_zyx(rotation_zyx(*a)) for a in noisy])[:, :2]
    err = tilt_error(np.repeat(R_true[None], len(reported), axis=0), reported)
    return np.sqrt(np.mean((err / tilt_std(reported, STD_RAD)) ** 2, axis=0))


@pytest.mark.parametrize("pitch_deg", [-89.99, -80.0, -60.0, 0.0, 45.0])
def test_tilt_std_is_the_estimators_angle_noise(pitch_deg):
    """:func:`tilt_std` is the horizontal block of the estimator's ``std^2 (E E^T + FLOOR^2 I)``
    at zero yaw (diagonal there); the residual's scatter under independent noise on the three
    angles is ``std^2 E E^T`` (Monte Carlo; the tilt about the pitch axis in full, about the
    other horizontal axis a floor the scatter stays under where ``E`` loses a rank)."""
    roll, pitch = 0.4, np.radians(pitch_deg)
    E = euler_rate_matrix(roll, pitch, 0.0)
    C = STD_RAD**2 * (E @ E.T + FLOOR**2 * np.eye(3))
    std = tilt_std(np.array([[roll, pitch]]), STD_RAD)[0]
    assert np.diag(C)[:2] == pytest.approx(std**2, rel=1e-12)
    assert C[0, 1] == pytest.approx(0.0, abs=1e-20)
    rms = _whitened_rms(roll, pitch)
    share = np.sqrt(np.diag(E @ E.T)[:2] / np.diag(E @ E.T + FLOOR**2 * np.eye(3))[:2])
    assert rms[1] == pytest.approx(share[1], abs=0.03)
    if np.cos(pitch) > 0.1:
        assert rms[0] == pytest.approx(share[0], abs=0.03)
    else:  # second order in the noise beats cos(pitch): still well under the floor
        assert rms[0] < 0.5


def test_anchored_start_recovers_the_tilt_at_pitch_near_minus_90():
    """A segment's predicted end 4 degrees off in tilt and 29 in yaw, the IMU's samples around
    the start at pitch -89.8 degrees with 0.005 rad of noise on each angle (so that pitch and
    roll jump as the reports pass the singularity): the anchored start's sensor is tilted as
    the samples' mean rotation (scipy's), which is the truth's to the noise, and turned about a
    horizontal axis only (the prediction's yaw kept)."""
    config = load_rig_config(shipped("config", "sim-rig"))
    truth = Truth(load_scene(config.scene_path), sim_config(config).truth)
    model, L = truth.model, truth.model.layout
    R_bs = rotation_zyx(0.05, -0.03, 0.02)

    def sensor(x):
        N, N_dot = model.nodes(x)
        _, _, R = truth.frame_motion(N[..., None], N_dot[..., None], np.zeros_like(N)[..., None])
        return R[0] @ R_bs

    def turned(x, G):
        out = x.copy()
        for part in (L.q, L.q_dot):
            out[part] = (G @ x[part].reshape(3, L.m)).ravel()
        return out

    x0 = truth.stepper.x.copy()
    x_true = turned(x0, rotation_zyx(0.3, np.radians(-89.8), 1.0) @ sensor(x0).T)
    R_true = sensor(x_true)
    x_pred = turned(x_true, _exp([0.05, -0.04, 0.5]))

    rng = np.random.default_rng(6)
    t = np.linspace(-0.05, 0.05, 11)
    noisy = euler_zyx(R_true) + rng.normal(0.0, STD_RAD, (len(t), 3))
    angles = np.array([euler_zyx(rotation_zyx(*a)) for a in noisy])
    assert np.ptp(angles[:, 0]) > 1.0  # roll jumps in the window
    bias = np.array([0.01, -0.02, 0.005])
    imu = np.column_stack([np.tile(bias, (len(t), 1)), np.zeros((len(t), 3)), angles])
    start = anchored(truth, x_pred, t, imu, 0.0, R_bs, bias)

    def angle_deg(u, v):
        return np.degrees(np.arccos(np.clip(u @ v, -1.0, 1.0)))

    R_start = sensor(start)
    # the samples' mean attitude as scipy averages rotations (quaternions), its up direction
    mean = Rotation.from_matrix([rotation_zyx(*a) for a in angles]).mean().as_matrix()
    assert angle_deg(R_start[2], mean[2]) < 0.005
    # the truth to the mean's noise: pitch's STD_RAD / sqrt(11), 4 sigma
    assert angle_deg(R_start[2], R_true[2]) < 4 * np.degrees(STD_RAD) / np.sqrt(len(t))
    turn = Rotation.from_matrix(R_start @ sensor(x_pred).T).as_rotvec()
    assert abs(turn[2]) < 1e-6
    assert np.linalg.norm(turn) > np.radians(3.0)  # it did correct the tilt


def test_the_turn_from_the_first_attitude_is_the_angle_between_them():
    """Against scipy's magnitude of the relative rotation, through pitch -90 degrees."""
    rng = np.random.default_rng(3)
    R = Rotation.random(50, random_state=rng)
    expected = (R[0].inv() * R).magnitude()
    np.testing.assert_allclose(turn_from_first(R.as_matrix()), expected, atol=1e-6)
    through = np.array([rotation_zyx(0.3, p, -0.2) for p in np.radians([-80.0, -90.0, -100.0])])
    np.testing.assert_allclose(turn_from_first(through), np.radians([0.0, 10.0, 20.0]), atol=1e-6)
