"""A live run's samples reach the filter in the order they were taken (fusion_horizon.py)."""

from types import SimpleNamespace

import pytest

from gyrohost.estimator.config import imu_taken_s
from gyrohost.estimator.fusion_horizon import FusionHorizon

LATENCY_S = 0.02
MAX_AGE_S = 0.03


class Recorder:
    """A filter that only notes what it is asked, in order, and keeps its time."""

    def __init__(self):
        self.config = SimpleNamespace(imu_latency_s=LATENCY_S)
        self.t = 0.0
        self.calls = []

    def _note(self, kind, t_s):
        self.calls.append((kind, round(t_s, 6)))
        self.t = max(self.t, t_s)

    def fuse_imu(self, t_s, *_):
        self._note("imu", imu_taken_s(self.config, t_s))

    def fuse_wheels(self, t_s, *_):
        self._note("wheels", t_s)

    def fuse_servos(self, t_s, *_):
        self._note("servos", t_s)

    def advance(self, t_s):
        self._note("advance", t_s)


@pytest.fixture
def horizon():
    return FusionHorizon(Recorder(), MAX_AGE_S)


def test_a_sample_waits_for_the_imu_sample_taken_before_it(horizon):
    """The wheels' sample taken at 0.105 s comes before the IMU's taken at 0.100 s (stamped
    0.120 s): it waits, and the two reach the filter in the order they were taken."""
    horizon.sample("fuse_imu", (0.110,))  # taken at 0.090
    horizon.sample("fuse_wheels", (0.105, None))
    horizon.sample("fuse_servos", (0.103, None, None))
    assert horizon.ekf.calls == [("imu", 0.09)]
    horizon.sample("fuse_imu", (0.120,))  # taken at 0.100
    assert horizon.ekf.calls == [("imu", 0.09), ("imu", 0.1)]
    horizon.sample("fuse_imu", (0.130,))  # taken at 0.110: the held ones before it
    assert horizon.ekf.calls[2:] == [("servos", 0.103), ("wheels", 0.105), ("imu", 0.11)]


def test_a_silent_imu_holds_nothing_back(horizon):
    horizon.sample("fuse_imu", (0.110,))
    horizon.sample("fuse_wheels", (0.120, None))
    horizon.tick(0.145)  # the IMU's newest came 0.035 s ago: past the 0.03 s
    assert horizon.ekf.calls == [("imu", 0.09), ("wheels", 0.12)]
    horizon.tick(0.160)  # the filter 0.04 s behind the tick: predicted to it
    assert horizon.ekf.calls[-1] == ("advance", 0.16)


def test_silence_counts_from_the_stamp_not_the_time_taken(horizon):
    """At 100 Hz the IMU's newest sample came at most a period before a tick, though it was
    taken the latency (0.02 s) earlier still: nothing is silent, the wheels' sample waits for
    the IMU's taken after it and no IMU sample comes after the filter passed its time."""
    horizon.sample("fuse_imu", (0.110,))  # taken at 0.090
    horizon.sample("fuse_wheels", (0.105, None))
    horizon.tick(0.125)  # 0.035 s after the newest IMU sample was taken, 0.015 s after it came
    horizon.sample("fuse_imu", (0.120,))  # taken at 0.100
    horizon.sample("fuse_imu", (0.130,))  # taken at 0.110
    assert horizon.ekf.calls == [("imu", 0.09), ("imu", 0.1), ("wheels", 0.105), ("imu", 0.11)]


def test_a_tick_while_the_imu_speaks_fuses_nothing_new(horizon):
    horizon.sample("fuse_imu", (0.110,))
    horizon.sample("fuse_wheels", (0.115, None))
    horizon.tick(0.115)
    assert horizon.ekf.calls == [("imu", 0.09)]
    horizon.flush()  # the run's end
    assert horizon.ekf.calls[-1] == ("wheels", 0.115)
