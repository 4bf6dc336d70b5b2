"""Wheel-board samples on the board's own clock: the host time of a sample is its ``t_us`` plus
the smallest delay seen over the link (:class:`DeviceClock`); the run loop fuses them there and
``gyrotens replay`` reconstructs the same times from the log."""

import numpy as np
import pytest
from fake_loop import Ekf, Stream

from gyrohost.config import load_rig_config
from gyrohost.estimator.config import EstimatorConfig, rig_keys
from gyrohost.estimator.sample_feed import DeviceClock, device_times, wheel_times
from gyrohost.resources import shipped
from gyrohost.run.dispatch import WheelHandler

OFFSET_S = 12.345  # the board booted this long before the host's clock reads 0 ... less
LINK_S = 0.0015  # the link's shortest delay, s


def arrivals(device_us, rng):
    """Arrival stamps of samples taken at ``device_us``: the offset, the link's shortest
    delay and a jitter of up to 11 ms (as the simulated rig's reader)."""
    return (
        np.asarray(device_us) * 1e-6 - OFFSET_S + LINK_S + rng.uniform(0.0, 0.011, len(device_us))
    )


def test_the_board_clock_takes_the_jitter_out_of_the_arrival_stamps():
    rng = np.random.default_rng(3)
    device_us = 20_000 * np.arange(300) + 13_000_000  # 50 Hz for 6 s
    arrival = arrivals(device_us, rng)
    t = device_times(arrival, device_us)
    true_s = device_us * 1e-6 - OFFSET_S + LINK_S  # what the link's fastest sample shows
    assert np.all(t <= arrival)  # never fused before it arrived
    # the jitter gone: a full window's smallest delay is within 0.5 ms of the link's shortest
    # but for 1 % of windows (uniform over 11 ms: 0.955^100)
    assert np.max(np.abs(t[100:] - true_s[100:])) < 5e-4
    assert np.ptp(arrival - true_s) > 0.01


def test_a_frame_s_time_on_the_wire_is_taken_off_the_link_s_delay():
    """No frame arrives sooner than its bits take on the wire: the clock puts a sample that much
    earlier than the fastest arrival shows (rig_keys gives the telemetry's, 38 bytes at the
    [wheelboard] baud)."""
    rng = np.random.default_rng(3)
    device_us = 20_000 * np.arange(300) + 13_000_000
    arrival = arrivals(device_us, rng)
    wire_s = 0.00038
    shifted = device_times(arrival, device_us, wire_s)
    np.testing.assert_allclose(shifted, device_times(arrival, device_us) - wire_s, atol=1e-12)
    keys = rig_keys(load_rig_config(shipped("config", "sim-rig")))
    assert keys["wheel_wire_s"] == pytest.approx(38 * 10 / 1_000_000)


def test_a_wrapped_board_clock_continues_and_a_reset_one_starts_again():
    rng = np.random.default_rng(4)
    wrap = DeviceClock.WRAP_US
    before = wrap - 20_000 * np.arange(50, 0, -1)
    after = 20_000 * np.arange(50) + 5_000
    device_us = np.concatenate([before, after])
    unwrapped = np.concatenate([before, after + wrap])
    arrival = arrivals(unwrapped, rng)
    t = device_times(arrival, device_us)
    true_s = unwrapped * 1e-6 - OFFSET_S + LINK_S
    # on through the wrap (the window's 50 smallest delays within 1 ms but for 1 %: 0.909^50)
    assert np.max(np.abs(t[50:] - true_s[50:])) < 1e-3
    clock = DeviceClock()
    for k in range(20):  # running 60 s, then the board resets: its clock starts at 0 again
        clock(100.0 + 0.02 * k, 60_000_000 + 20_000 * k)
    assert clock(101.0, 2_000) == pytest.approx(101.0)  # no history: its own arrival


def test_the_run_loop_fuses_the_wheels_where_replay_puts_them():
    class Telemetry:
        omega_rad_s, drive, seq, status, faults = (75.0,) * 4, (0,) * 4, 0, 0, 0

    rng = np.random.default_rng(5)
    device_us = 20_000 * np.arange(80) + 3_000_000
    arrival = arrivals(device_us, rng)
    stream, ekf = Stream(), Ekf()
    handler = WheelHandler(stream, 4, EstimatorConfig())
    for a, d in zip(arrival, device_us, strict=True):
        sample = Telemetry()
        sample.t_us = int(d)
        handler.take(float(a), sample, ekf)
    assert [r[0] for r in stream.rows] == list(arrival)  # the log keeps the arrival stamps
    logged = np.array(
        [(r[0], r[5]) for r in stream.rows], dtype=[("t_s", float), ("device_t_us", float)]
    )
    assert np.array_equal(ekf.fused_at, wheel_times(logged, EstimatorConfig()))
    by_arrival = wheel_times(logged, EstimatorConfig(wheel_times="arrival"))
    assert np.array_equal(by_arrival, arrival)
