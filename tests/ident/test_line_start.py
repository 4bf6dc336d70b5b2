"""The filter stage's start along the IMU's yaw (ident/profile.line_start, ident/staged):
from the stage before's value, the smooth minimum of the cost within +-3 of its sigmas."""

from types import SimpleNamespace

import numpy as np
import pytest

from gyrohost.ident import profile, staged
from gyrohost.ident.params import Param

TRUE_YAW = 0.009


class Likelihood:
    """A cost smooth near :data:`TRUE_YAW` (a parabola, 1e5 per rad^2) and, more than 0.02 rad
    from it, jumping by hundreds (the filter's linearisation broken at moments of the run);
    rough by a unit everywhere. Parameter 1 is the yaw."""

    def cost(self, theta) -> float:
        yaw = theta[1]
        smooth = 3470.0 + 1e5 * (yaw - TRUE_YAW) ** 2
        ripple = 1.0 * np.sin(yaw / 7e-4)
        jumps = 150.0 * np.floor(abs(yaw - TRUE_YAW) / 0.007) if abs(yaw - TRUE_YAW) > 0.02 else 0
        return smooth + ripple + jumps

    def batch(self, thetas):
        return [np.array([np.sqrt(2.0 * self.cost(t))]) for t in thetas]


def test_the_start_moves_into_the_smooth_basin_from_out_in_the_jumps():
    theta = np.array([0.0, 0.056])  # started 2.7 deg out, in the jumps
    start, samples = profile.line_start(Likelihood(), theta, 1, 0.028)
    assert start[0] == 0.0
    # in the smooth basin (+-0.02), within a third of the samples' spacing (0.014)
    assert start[1] == pytest.approx(TRUE_YAW, abs=0.005)
    assert len(samples) == 13 and samples[0][0] == pytest.approx(-0.084)


def test_the_vertex_of_the_lowest_samples_or_the_lowest_where_not_convex():
    offsets = np.array([-2.0, -1.0, 0.0, 1.0, 2.0])
    assert profile.lowest_vertex(offsets, (offsets - 0.4) ** 2) == pytest.approx(0.4)
    assert profile.lowest_vertex(offsets, np.array([0.0, 2.0, 2.5, 2.0, 0.1])) == -2.0


def structure_with(sigma_yaw: float, determined: bool = True):
    params = [Param("mounting.roll", "mounting", False, 0.0, "rad"),
              Param("mounting.yaw", "mounting", False, 0.0, "rad")]  # fmt: skip
    return SimpleNamespace(
        params=params, sigma=np.array([0.001, sigma_yaw]), determined=np.array([True, determined])
    )


def test_the_yaw_line_takes_the_output_errors_sigma_where_it_determined_the_yaw():
    params = [Param(n, "mounting", False, 0.0, "rad") for n in ("mounting.yaw", "imu_latency")]
    assert staged.yaw_line(structure_with(0.028), params) == (0, 0.028)
    assert staged.yaw_line(structure_with(2.0, determined=False), params) is None
    assert staged.yaw_line(structure_with(0.028), params[1:]) is None


def test_the_line_goes_on_while_its_lowest_sample_is_the_outermost():
    """The stage before 4 sigmas off (its sigma too small): the samples go on past 3 sigmas."""
    theta = np.array([0.0, TRUE_YAW - 4 * 0.005])
    start, samples = profile.line_start(Likelihood(), theta, 1, 0.005)
    assert start[1] == pytest.approx(TRUE_YAW, abs=0.0025)  # within the samples' spacing
    assert max(o for o, _ in samples) == pytest.approx(6 * 0.005)  # up to LINE_REACH sigmas
