"""The simulated rig in process: the three drivers against it, truth following the devices,
the IMU seeing the truth, run-time faults reaching the drivers as their named errors."""

import queue
import time

import numpy as np
import pytest
from control_beat import start_control_thread

from gyrohost.config import ServoBusConfig, rig_config_from_dict
from gyrohost.drivers import wheelboard as wb
from gyrohost.drivers.errors import ImuTimeoutError, ServoCommError, ServoFaultError
from gyrohost.drivers.imu import Bwt61Driver
from gyrohost.drivers.mx12 import steps_per_metre
from gyrohost.drivers.servos import StringServoBus
from gyrohost.simrig.config import sim_config
from gyrohost.simrig.errors import FaultCommandError, RigError
from gyrohost.simrig.sim import SimulatedRig

SPIN = 74.87462492
L0 = 0.43105229381822  # both D-bar strings at t = 0, m
CONFIG = rig_config_from_dict(
    {
        "scene": "dbar-gyro",
        "servos": {
            "servo": [
                {"name": "left", "id": 1, "pulley_radius_m": 0.01, "length_at_zero_m": L0,
                 "min_length_m": 0.1, "max_length_m": 0.7, "max_speed_m_s": 0.1,
                 "string": "s13"},
                {"name": "right", "id": 2, "pulley_radius_m": 0.01, "length_at_zero_m": L0,
                 "min_length_m": 0.1, "max_length_m": 0.7, "max_speed_m_s": 0.1,
                 "string": "s24"},
            ]
        },
        "sim": {"imu": {"gyro_bias_std_rad_s": 0.0, "accel_bias_std_m_s2": 0.0}},
    }
)  # fmt: skip


@pytest.fixture
def rig():
    """A simulated-clock rig with the three drivers open; yields (rig, imu, wheels, servos)."""
    with SimulatedRig(CONFIG, clock="sim") as rig:
        imu = Bwt61Driver(rig.paths["imu"], timeout_s=0.05).open()
        events: queue.Queue = queue.Queue()
        wheels = wb.WheelBoard(rig.paths["wheels"], on_fault=events.put)
        wheels.events = events
        wheels.connect()
        # the host beats on wall time, the rig ticks faster (see sim.py): its longest timeout
        wheels.set_param("HEARTBEAT_MS", 1000)
        start_control_thread(wheels)
        bus = StringServoBus(ServoBusConfig(port=rig.paths["servos"], servo=CONFIG.servos.servo))
        bus.open().configure()
        yield rig, imu, wheels, bus
        wheels.close()
        bus.close()
        imu.close()
    rig.check()


def test_truth_follows_servos_and_wheels_and_the_imu_sees_the_tilt(rig):
    rig, imu, wheels, bus = rig
    wheels.set_speeds([SPIN, -SPIN, -SPIN, SPIN])
    rig.advance(1.2)  # 0.75 s of ramp at 100 rad/s^2, then the 50 ms motor lag
    # within five times the speed loop's error (std speed_error_std_rad_s) of the setpoints
    atol = 5.0 * sim_config(rig.config).wheels.speed_error_std_rad_s
    np.testing.assert_allclose(rig.truth_wheel_speeds(), [SPIN, -SPIN, -SPIN, SPIN], atol=atol)
    assert np.max(np.abs(rig.truth_nodes()[2])) < 1e-9  # no string moved yet: still planar
    imu.poll()  # discard the samples so far
    rig.start_recording()
    start = rig.t_s
    goal = L0 - 0.12
    bus.command_lengths({"left": goal, "right": np.sqrt(4 * 0.3048**2 - goal**2)})
    samples = []
    for _ in range(6):  # read as we go: a pty holds only a few kB (33 bytes per sample)
        rig.advance(0.25)
        samples += imu.poll()
    # the truth's rest length is the shaft's, the read its count: within the hold band
    band_m = sim_config(rig.config).servos.hold_band_steps / steps_per_metre(CONFIG.servos.servo[0])
    read = list(bus.read_lengths().values())
    np.testing.assert_allclose(rig.truth_rest_lengths(), read, rtol=0, atol=band_m)
    assert rig.truth_rest_lengths()[0] == pytest.approx(goal, abs=1e-3)  # 0.1 m/s: 1.2 s
    record = rig.recording()
    z = record.N[-1, 2]
    assert z[0] < -0.005 and z[2] > 0.005  # n1 and n3 leave the plane the gyroscopic way
    # IMU samples come every 10 ms of rig time: compare with the rate of the recorded attitude.
    assert len(samples) == pytest.approx(150, abs=2)
    rates = np.array([s.omega_rad_s for s in samples])
    R = record.R_wb
    dR = np.einsum("kji,kjl->kil", R[:-1], R[1:])  # R_k^T R_k+1
    truth_rate = np.stack([dR[:, 2, 1] - dR[:, 1, 2], dR[:, 0, 2] - dR[:, 2, 0]], 1)
    truth_rate = truth_rate / (2 * np.diff(record.t_s)[:, None])
    t_truth = record.t_s[:-1] + 0.5 * np.diff(record.t_s)
    t_imu = start + 0.01 * np.arange(1, len(samples) + 1)
    for axis in (0, 1):
        expected = np.interp(t_imu, t_truth, truth_rate[:, axis])
        assert np.max(np.abs(rates[:, axis] - expected)) < 0.02 + 0.05 * np.max(np.abs(expected))
    assert np.max(np.abs(rates[:, 1])) > 0.1  # a real tilt rate, not noise


def test_faults_reach_the_drivers_as_named_errors(rig):
    rig, imu, wheels, bus = rig
    rig.advance(0.05)
    imu.poll()
    rig.inject("imu", "silence", duration_s=0.2)
    rig.advance(0.15)
    imu.poll()  # a sample sent before the silence that the first poll missed (a pty passes
    # bytes on a moment after they are written)
    with pytest.raises(ImuTimeoutError):
        imu.read_sample(timeout_s=0.05)
    rig.advance(0.1)
    assert imu.read_sample(timeout_s=0.5)  # back after 0.2 s

    rig.command("fault imu corrupt 5")
    rig.advance(0.05)
    imu.poll()
    assert imu.stats.corrupt_frames + imu.stats.dropped_frames >= 1

    rig.command("fault servos overload 2 0.1")
    with pytest.raises(ServoFaultError, match="overload") as err:
        bus.read_states()
    assert err.value.servo_id == 2
    rig.advance(0.12)
    bus.set_torque(True)  # the latched overload clears with torque on
    bus.read_states()
    rig.command("fault servos timeout 1")
    with pytest.raises(ServoCommError):
        bus.read_states()
    rig.command("fault servos clear")
    bus.read_states()

    seq = wheels.last_telemetry.seq
    rig.command("fault wheels watchdog 0.05")
    for _ in range(3):
        rig.advance(0.05)
    assert wheels.events.get(timeout=2.0) == ["WATCHDOG_RESET"]
    assert wheels.last_telemetry.seq < seq

    rig.command("fault wheels stall 0.1")
    rig.advance(0.2)
    assert rig.wheels.faults.counters.bursts >= 1

    with pytest.raises(FaultCommandError, match="unknown imu fault 'reset'"):
        rig.command("fault imu reset")
    with pytest.raises(FaultCommandError, match="unknown device 'gps'"):
        rig.inject("gps", "silence")
    with pytest.raises(FaultCommandError, match="servo ID 9 is not on the bus"):
        rig.inject("servos", "overload", servo_id=9)
    assert rig.command("stats").startswith("rates: imu")


def test_reset_puts_the_rig_back_where_the_scene_starts(rig):
    rig, imu, wheels, bus = rig
    nodes0 = rig.truth_nodes()
    wheels.set_speeds([SPIN, -SPIN, -SPIN, SPIN])
    rig.advance(1.0)
    goal = L0 - 0.1
    bus.command_lengths({"left": goal, "right": np.sqrt(4 * 0.3048**2 - goal**2)})
    for _ in range(4):
        rig.advance(0.25)
        imu.poll()
    assert np.max(np.abs(rig.truth_nodes() - nodes0)) > 0.01  # moved, shape and tilt
    assert rig.truth_rest_lengths()[0] == pytest.approx(goal, abs=1e-3)
    wheels.stop_all()  # the host's safe state: torque stays on, the goals are held
    bus.hold()
    assert rig.command("reset") == (
        "reset: truth at the scene's initial state, servos at their start, wheels at rest"
    )
    np.testing.assert_array_equal(rig.truth_nodes(), nodes0)
    np.testing.assert_array_equal(rig.truth_wheel_speeds(), np.zeros(4))
    rig.advance(0.2)  # the held servos stay where the reset put them: nothing moves back
    assert list(bus.read_lengths().values()) == pytest.approx([L0, L0], abs=1e-9)
    # the servos' start is held within their band (7.7 um of string): the rhombus settles to it
    np.testing.assert_allclose(rig.truth_nodes(), nodes0, atol=1e-6)
    assert wheels.last_telemetry.omega_rad_s == pytest.approx([0.0] * 4, abs=0.05)
    imu.poll()
    rig.advance(0.05)
    sample = imu.poll()[-1]
    assert np.max(np.abs(sample.euler_rad)) < 0.01 and np.max(np.abs(sample.omega_rad_s)) < 0.01


def test_advance_needs_the_sim_clock():
    rig = SimulatedRig(CONFIG, clock="real")
    try:
        with pytest.raises(RigError, match="needs clock='sim'"):
            rig.advance(0.1)
    finally:
        rig.close()
    with pytest.raises(ValueError, match="clock must be"):
        SimulatedRig(CONFIG, clock="fast")


def test_a_truth_sample_is_read_at_one_step_while_the_truth_moves():
    """Read by another thread, as the rig process streams it: each sample's state is the
    truth's at the sample's own time, never a later step's."""
    with SimulatedRig(CONFIG, clock="real") as rig:
        bus = StringServoBus(ServoBusConfig(port=rig.paths["servos"], servo=CONFIG.servos.servo))
        bus.open().configure()
        rig.start_recording()
        goal = L0 - 0.05
        bus.command_lengths({"left": goal, "right": np.sqrt(4 * 0.3048**2 - goal**2)})
        samples, times, end = [], set(), time.monotonic() + 3.0
        # as fast as the GIL lets this thread in; the times counted as they come, since a set
        # rebuilt from every sample each pass grows quadratic and starves the truth's thread
        while time.monotonic() < end and len(times) < 60:
            samples.append(rig.truth_sample())
            times.add(samples[-1][0])
        record = rig.recording()
        bus.close()
    rig.check()

    steps = {t: k for k, t in enumerate(record.t_s)}
    taken = [(steps[t], N, rest) for t, _, N, _, rest in samples if t in steps]
    assert len({k for k, _, _ in taken}) >= 30  # many steps, each read several times
    for k, N, rest in taken:
        np.testing.assert_array_equal(N, record.N[k])
        np.testing.assert_array_equal(rest, record.rest_length_m[k])
    moved = np.max(np.abs(record.N[-1] - record.N[0]))
    assert moved > 1e-3, f"the truth moved only {moved} m: nothing to tell the steps apart"


def test_every_step_of_the_truth_reaches_its_reader_once():
    """The rig process sends every step's truth (sim.truth_steps), so that a reader
    interpolating between them has what the physics held between its steps: consecutive steps,
    each once, each the state the recording has at that step, after the last read."""
    with SimulatedRig(CONFIG, clock="sim") as rig:
        assert rig.truth_steps() == []  # none kept before asked
        rig.keep_truth_steps()
        rig.start_recording()
        rig.advance(0.05)
        first = rig.truth_steps()
        rig.advance(0.05)
        second = rig.truth_steps()
        record = rig.recording()
    rig.check()
    dt = rig.truth.dt_s
    times = [step[2] for step in first + second]
    assert len(times) >= round(0.1 / dt) - 1
    assert np.diff(times) == pytest.approx(dt)  # every step, in order, none twice
    assert second[0][2] == pytest.approx(first[-1][2] + dt)
    steps = {t: k for k, t in enumerate(record.t_s)}
    for _, _, t, _, N, _, rest in first + second:
        if t in steps:
            np.testing.assert_array_equal(N, record.N[steps[t]])
            np.testing.assert_array_equal(rest, record.rest_length_m[steps[t]])
    assert sum(step[2] in steps for step in second) >= len(second) - 1
