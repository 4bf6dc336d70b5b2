"""Tilt of the D-bar plane against rotations of known angle."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyrohost.control import Attitude
from gyrohost.control.attitude import TiltMeter, body_frame_of
from gyrohost.resources import shipped
from gyrotensegrity import Model, load_scene


def rotated(N, axis, angle):
    return Rotation.from_rotvec(np.asarray(axis, float) * angle).as_matrix() @ N


@pytest.mark.parametrize("angle", [-2.5, -0.3, 0.0, 0.1, 1.2, 3.0])
def test_rotation_about_the_tilt_axis(dbar, angle):
    att = Attitude(dbar)
    np.testing.assert_allclose(att.axis, [0.0, 1.0, 0.0], atol=1e-12)
    N = rotated(dbar.structure.N0, [0, 1, 0], angle)
    assert att.tilt(N) == pytest.approx(angle, abs=1e-12)


def test_rotation_about_other_axes_is_no_tilt(dbar):
    att = Attitude(dbar)
    for axis in ([1, 0, 0], [0, 0, 1]):
        assert att.tilt(rotated(dbar.structure.N0, axis, 0.4)) == pytest.approx(0.0, abs=1e-12)


def test_tilt_rate_of_a_rigid_rotation(dbar):
    att = Attitude(dbar)
    N = rotated(dbar.structure.N0, [0, 1, 0], 0.7)
    w = np.array([0.0, -1.3, 0.0])
    assert att.tilt_rate(N, np.cross(w, N.T).T) == pytest.approx(-1.3, rel=1e-6)


@pytest.mark.parametrize("angle", [-1.4, -0.2, 0.5, 1.5])
def test_the_tilt_is_the_body_frames_pitch_for_a_turn_about_n2_n4(dbar, angle):
    """The D-bar's [attitude] frame is the plane frame: a turn about n2-n4 (its y axis) is a
    tilt and a pitch of the same angle, no roll and no yaw."""
    N = rotated(dbar.scene.positions, [0, 1, 0], angle)
    assert TiltMeter(dbar).tilt(N) == pytest.approx(angle, abs=1e-12)
    np.testing.assert_allclose(body_frame_of(dbar).attitude(N).rpy_rad, [0, angle, 0], atol=1e-12)


def test_a_scene_without_an_attitude_table_has_no_body_frame():
    assert body_frame_of(Model(load_scene(shipped("scene", "double-pendulum")))) is None
