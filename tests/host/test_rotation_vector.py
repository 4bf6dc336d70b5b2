"""geometry.rotation_vector (the fast path's log map) against scipy's Rotation.as_rotvec.

Rotations drawn over the whole range of angles, from 1e-9 rad (the series branch) through the
quaternion's branch changes to a hair below pi; both are exact to a few ulp, so 1e-13 of the
angle (at least 1e-15 rad) fails on any wrong branch or sign."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyrohost.geometry import rotation_vector


@pytest.mark.parametrize("angle_rad", [0.0, 1e-9, 1e-4, 1e-3, 2e-3, 0.3, 1.5, 3.0, np.pi - 1e-7])
def test_rotation_vector_equals_scipys(angle_rad):
    axes = np.random.default_rng(5).normal(size=(50, 3))
    for axis in axes:
        v = angle_rad * axis / np.linalg.norm(axis)
        R = Rotation.from_rotvec(v).as_matrix()
        got, want = rotation_vector(R), Rotation.from_matrix(R).as_rotvec()
        assert np.max(np.abs(got - want)) <= 1e-13 * max(angle_rad, 1e-2)
