"""Tilt of the D-bar plane against rotations of known angle."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyrohost.control import Attitude


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
