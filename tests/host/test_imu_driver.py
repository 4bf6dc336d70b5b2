"""BWT61CL driver against its emulator over a pty: truth recovery, commands, faults."""

import queue
import time
from dataclasses import replace

import numpy as np
import pytest

from gyrohost.config import ImuConfig
from gyrohost.drivers.errors import ImuConfigError, ImuError, ImuTimeoutError
from gyrohost.drivers.imu import Bwt61Driver
from gyrohost.geometry import euler_zyx, rotation_zyx
from gyrohost.run.devices import ImuReader
from gyrohost.run.errors import DeviceFault
from gyrohost.simrig.config import ImuEmuConfig, StreamFaultConfig
from gyrohost.simrig.imu_emu import Bwt61Emulator, ImuTruth

G = 9.80665
QUIET = ImuEmuConfig(gyro_bias_std_rad_s=0.0, accel_bias_std_m_s2=0.0)


@pytest.fixture
def rig():
    """Factory: start an emulator with the given settings and open a driver on its pty."""
    opened = []

    def make(emu=QUIET, imu=None, truth_source=None):
        device = Bwt61Emulator(emu, imu, truth_source).start()
        driver = Bwt61Driver(device.slave_path, timeout_s=2.0).open()  # generous: loaded CPUs
        opened.append((device, driver))
        return device, driver

    yield make
    for device, driver in opened:
        driver.close()
        device.close()
        assert device.loop_error is None


def collect(driver, n):
    return [driver.read_sample() for _ in range(n)]


def test_rotating_body_is_recovered_in_si_units(rig):
    R = rotation_zyx(0.2, -0.1, 1.0)
    omega = np.array([0.1, -0.2, 0.3])
    force = R.T @ np.array([0.0, 0.0, G]) + np.array([0.5, 0.0, 0.0])
    device, driver = rig()
    device.set_truth(omega, force, R)
    driver.read_sample()
    samples = collect(driver, 40)
    np.testing.assert_allclose(np.mean([s.omega_rad_s for s in samples], 0), omega, atol=2e-3)
    np.testing.assert_allclose(np.mean([s.accel_m_s2 for s in samples], 0), force, atol=0.02)
    np.testing.assert_allclose(
        np.mean([s.euler_rad for s in samples], 0), [0.2, -0.1, 1.0], atol=2e-3
    )
    assert samples[-1].temperature_degC == pytest.approx(25.0, abs=0.01)
    # Arrival stamps: non-decreasing (two samples read in one chunk share a stamp).
    stamps = [s.t_ns for s in samples]
    assert stamps == sorted(stamps) and stamps[-1] > stamps[0]
    assert driver.stats.corrupt_frames == 0 and driver.stats.dropped_frames == 0


def test_noise_is_near_the_configured_density(rig):
    device, driver = rig()
    samples = collect(driver, 150)
    std = np.std([s.accel_m_s2 for s in samples], axis=0)
    expected = QUIET.accel_noise_density_m_s2_rthz * np.sqrt(100 / 2)
    assert np.all((0.7 * expected < std) & (std < 1.3 * expected))


def test_mounting_rotation_maps_body_axes_to_sensor_axes(rig):
    imu = ImuConfig(mounting_rpy_rad=(0.0, 0.0, np.pi / 2))  # sensor x along body y
    device, driver = rig(imu=imu)
    device.set_truth([1.0, 0.0, 0.0], [0.0, 0.0, G], np.eye(3))
    driver.read_sample()
    samples = collect(driver, 10)
    np.testing.assert_allclose(np.mean([s.omega_rad_s for s in samples], 0), [0, -1, 0], atol=3e-3)
    assert np.mean([s.euler_rad[2] for s in samples]) == pytest.approx(np.pi / 2, abs=3e-3)


def test_truth_source_is_called_with_time(rig):
    calls = []

    def truth(t_s):
        calls.append(t_s)
        return ImuTruth(omega_rad_s=np.array([0.0, 0.0, 0.5]))

    device, driver = rig(truth_source=truth)
    s = collect(driver, 3)[-1]
    assert s.omega_rad_s[2] == pytest.approx(0.5, abs=3e-3)
    assert len(calls) >= 3 and calls == sorted(calls)


def test_zero_yaw_command(rig):
    device, driver = rig()
    device.set_truth(np.zeros(3), [0, 0, G], rotation_zyx(0.0, 0.0, 1.0))
    # a sample encoded before the new truth may still be on the wire
    _wait_for(lambda: abs(driver.read_sample().euler_rad[2] - 1.0) < 5e-3)
    driver.zero_yaw()
    _wait_for(lambda: 0x52 in device.commands_seen)
    driver.read_sample()
    assert abs(driver.read_sample().euler_rad[2]) < 5e-3


def test_accelerometer_calibration_removes_the_bias(rig):
    device, driver = rig(emu=replace(QUIET, accel_bias_std_m_s2=0.3, seed=3))
    bias = device.accel_bias_m_s2.copy()
    before = np.mean([s.accel_m_s2 for s in collect(driver, 20)], 0)
    np.testing.assert_allclose(before - [0, 0, G], bias, atol=0.03)
    driver.calibrate_accelerometer()
    _wait_for(lambda: 0x67 in device.commands_seen)
    driver.read_sample()
    after = np.mean([s.accel_m_s2 for s in collect(driver, 20)], 0)
    np.testing.assert_allclose(after, [0, 0, G], atol=0.03)


def test_rate_and_mounting_commands(rig):
    device, driver = rig()
    driver.set_rate(20)
    driver.set_mounting("vertical")
    _wait_for(lambda: device.vertical and device.rate_hz == 20)
    assert driver.baud == 9600 and device.baud == 9600
    driver.poll()
    stamps = [s.t_ns for s in collect(driver, 6)]
    assert np.median(np.diff(stamps)) > 30e6  # 50 ms period (100 Hz would be 10 ms)
    driver.set_rate(100)
    driver.set_mounting("horizontal")
    _wait_for(lambda: not device.vertical and device.rate_hz == 100)
    with pytest.raises(ImuConfigError, match="50 Hz"):
        driver.set_rate(50)
    with pytest.raises(ImuConfigError, match="sideways"):
        driver.set_mounting("sideways")


def test_corrupt_bytes_are_counted_and_never_passed_on(rig):
    faults = StreamFaultConfig(corrupt_byte_prob=0.01, seed=5)
    device, driver = rig(emu=replace(QUIET, faults=faults))
    samples = collect(driver, 60)
    assert driver.stats.corrupt_frames > 0
    assert driver.stats.dropped_frames >= driver.stats.corrupt_frames
    for s in samples:
        np.testing.assert_allclose(s.accel_m_s2, [0, 0, G], atol=0.2)
        np.testing.assert_allclose(s.euler_rad, 0.0, atol=0.02)


def test_dropped_bytes_lose_frames_that_are_counted(rig):
    device, driver = rig()
    driver.read_sample()
    device.faults.drop_next(3)
    collect(driver, 3)
    assert driver.stats.dropped_frames >= 1


def test_silence_times_out_then_recovers(rig):
    device, driver = rig()
    driver.read_sample()
    device.faults.set_silent(True)
    time.sleep(0.05)
    driver.poll()
    with pytest.raises(ImuTimeoutError, match="no complete sample"):
        driver.read_sample(timeout_s=0.1)
    device.faults.set_silent(False)
    assert driver.read_sample().accel_m_s2[2] == pytest.approx(G, abs=0.2)


def test_bluetooth_like_stall_delivers_a_burst_without_loss(rig):
    device, driver = rig()
    driver.read_sample()
    device.faults.stall_for(0.3, time.monotonic())
    with pytest.raises(ImuTimeoutError):
        driver.read_sample(timeout_s=0.15)
    burst = []
    deadline = time.monotonic() + 1.0
    while len(burst) < 10 and time.monotonic() < deadline:
        burst += driver.poll()
    assert device.faults.counters.bursts >= 1
    assert len(burst) >= 10
    assert burst[9].t_ns - burst[0].t_ns < 5e6  # ten samples within 5 ms: a burst
    assert driver.stats.dropped_frames == 0


def test_port_errors_are_the_drivers_own():
    with pytest.raises(ImuError, match="cannot open /nonexistent/tty"):
        Bwt61Driver("/nonexistent/tty").open()
    with pytest.raises(ImuError, match="not open"):
        Bwt61Driver("/dev/null").poll()


def test_euler_round_trip():
    for angles in [(0.1, -0.4, 2.5), (-3.0, 1.2, -0.3)]:
        np.testing.assert_allclose(euler_zyx(rotation_zyx(*angles)), angles, atol=1e-12)


def _wait_for(condition, timeout_s=1.0):
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "condition not met in time"
        time.sleep(0.005)


def test_a_garbage_stream_is_counted_in_the_silence_fault(rig):
    """1 s of garbage (every byte corrupted): the reader stops on silence and says what it saw."""
    device, driver = rig()
    driver.read_sample()
    out = queue.Queue()
    reader = ImuReader(driver, out, silence_s=0.5)
    device.faults.corrupt_next(3300)  # 1 s of output at 100 Hz, 33 bytes per sample
    reader.start()
    try:
        fault = out.get(timeout=5.0)
        while not isinstance(fault, DeviceFault):
            fault = out.get(timeout=5.0)
    finally:
        reader.stop()
    message = str(fault)
    assert message.startswith("imu: no sample for 0.5 s (")
    assert "0 frames" in message and "0 samples" in message
    skipped = int(message.split("skipped ")[1].split(" bytes")[0])
    assert skipped > 1000  # about 0.5 s of garbage at 3300 bytes/s
