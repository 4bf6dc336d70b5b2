"""The rig's truth model: inputs from the devices, IMU frame kinematics against closed forms."""

import math
from pathlib import Path

import numpy as np
import pytest

from gyrohost.config import ServoConfig
from gyrohost.geometry import rotation_zyx
from gyrohost.resources import shipped
from gyrohost.simrig.config import TruthConfig
from gyrohost.simrig.errors import RigSetupError
from gyrohost.simrig.truth import Truth, rig_scene
from gyrotensegrity import Model, SimulationError, Stepper, load_scene
from gyrotensegrity.diagnostics import highest_frequency
from gyrotensegrity.simulate import RK4_STABLE

SCENE = load_scene(shipped("scene", "dbar-gyro"))
LEFT = ServoConfig(name="left", id=1, pulley_radius_m=0.01, string="s13")
G = 9.80665


def test_rig_scene_has_speed_wheels_at_rest_and_scaled_inertia():
    plant = Model(rig_scene(SCENE, wheel_inertia_scale=1.2))
    nominal = Model(SCENE)
    assert plant.wheel_modes == ["speed"] * 4
    assert np.all(plant.spin0 == 0.0)
    np.testing.assert_allclose(plant.J3, 1.2 * nominal.J3, rtol=1e-12)
    np.testing.assert_allclose(plant.m_t, nominal.m_t)  # masses unchanged


def test_rest_length_follows_the_servo_with_the_configured_lag():
    lag = 0.05
    truth = Truth(SCENE, TruthConfig(dt_s=0.005, servo_lag_s=lag), [LEFT])
    start = truth.rest_length_m.copy()
    for _ in range(10):  # 50 ms = one time constant
        truth.step({1: start[0] - 0.01}, [0.0] * 4)
    moved = start[0] - truth.rest_length_m[0]
    assert moved == pytest.approx(0.01 * (1 - math.exp(-1.0)), rel=1e-9)
    assert truth.rest_length_m[1] == start[1]  # no servo winds s24: it keeps its rest length


def test_a_servo_move_within_a_step_moves_the_string_when_the_servo_does():
    """A servo covers 2 mm between 1 and 3 ms of a 5 ms step, then holds. Stepped through its
    turns, the truth moves as one stepped every 0.1 ms along the same path (to RK4's error, a
    hundredth of the difference at most); one line from the step's start to its end instead
    moves the string from its first millisecond to its last, and the nodes end 1 um away."""

    def path(t):  # the servo's string length, m, at t s
        return 0.43105229381822 - 0.002 * min(max((t - 0.001) / 0.002, 0.0), 1.0)

    spin = [0.0] * 4  # the wheels at rest: the string alone moves the nodes
    turned = Truth(SCENE, TruthConfig(dt_s=0.005), [LEFT])
    turned.step({1: path(0.005)}, spin, [(0.001, {1: path(0.001)}), (0.003, {1: path(0.003)})])
    fine = Truth(SCENE, TruthConfig(dt_s=0.0001), [LEFT])
    for k in range(1, 51):
        fine.step({1: path(k * 0.0001)}, spin)
    line = Truth(SCENE, TruthConfig(dt_s=0.005), [LEFT])
    line.step({1: path(0.005)}, spin)
    assert turned.t_s == fine.t_s == 0.005
    assert turned.rest_length_m == pytest.approx(fine.rest_length_m, abs=1e-12)
    scale = np.max(np.abs(line.nodes() - fine.nodes()))
    assert np.max(np.abs(turned.nodes() - fine.nodes())) < 1e-2 * scale


def test_turns_closer_than_a_microsecond_are_one():
    """Two servos arriving together, 1e-12 s apart by round-off, and a turn at the step's end:
    no piece of (almost) no length is stepped, and the string ends where the servos are."""
    truth = Truth(SCENE, TruthConfig(dt_s=0.005), [LEFT])
    end = truth.rest_length_m[0] - 0.001
    turns = [(0.002, {1: end}), (0.002 + 1e-12, {1: end}), (0.005 - 1e-12, {1: end})]
    before = len(truth._history)  # one entry per piece stepped
    truth.step({1: end}, [0.0] * 4, turns)
    assert len(truth._history) - before == 2  # to the first turn, then to the step's end
    assert truth.t_s == 0.005 and truth.rest_length_m[0] == end


def test_wheel_spins_follow_the_board_in_scene_order():
    truth = Truth(SCENE, TruthConfig(), [])
    truth.step({}, [1.0, -2.0, 3.0, -4.0])
    np.testing.assert_array_equal(truth.wheel_input_rad_s, [1.0, -2.0, 3.0, -4.0])
    assert truth.model.wheel_speeds(truth.stepper.x, truth.u).tolist() == [1.0, -2.0, 3.0, -4.0]


def rigidly_rotating(truth, omega_world):
    """Give the structure the velocity field of a rigid rotation about the origin."""
    N, _ = truth.model.nodes(truth.stepper.x)
    N_dot = np.cross(omega_world[:, None], N, axis=0)
    truth.set_state(truth.model.state(N, N_dot, omega=np.zeros(4)))


def test_imu_frame_of_a_rigid_rotation_matches_the_closed_form():
    truth = Truth(SCENE, TruthConfig(dt_s=0.005), [])
    omega = np.array([0.3, -0.2, 0.5])
    rigidly_rotating(truth, omega)
    sample = truth.imu_truth(0.0)
    np.testing.assert_allclose(sample.R_wb, np.eye(3), atol=1e-12)  # D-bar frame = world
    np.testing.assert_allclose(sample.omega_rad_s, omega, atol=1e-6)
    # The origin (centre of the rhombus) does not accelerate: the IMU feels gravity only.
    np.testing.assert_allclose(sample.specific_force_m_s2, [0.0, 0.0, G], atol=1e-6)

    truth = Truth(SCENE, TruthConfig(dt_s=0.005), [])
    rigidly_rotating(truth, np.array([0.0, 0.0, 0.5]))  # about a principal axis: steady
    for _ in range(200):
        truth.step({}, [0.0] * 4)
    sample = truth.imu_truth(truth.t_s)
    np.testing.assert_allclose(sample.R_wb, rotation_zyx(0.0, 0.0, 0.5), atol=1e-6)
    np.testing.assert_allclose(sample.omega_rad_s, [0.0, 0.0, 0.5], atol=1e-6)
    np.testing.assert_allclose(sample.specific_force_m_s2, [0.0, 0.0, G], atol=1e-5)


def test_imu_latency_returns_the_older_truth_and_recording():
    truth = Truth(SCENE, TruthConfig(dt_s=0.005, imu_latency_s=0.05), [])
    rigidly_rotating(truth, np.array([0.0, 0.0, 1.0]))
    truth.start_recording()
    for _ in range(40):
        truth.step({}, [0.0] * 4)
    record = truth.recording()
    assert record.N.shape == (40, 3, 4) and record.R_wb.shape == (40, 3, 3)
    assert record.t_s[-1] == pytest.approx(0.2)
    delayed = truth.imu_truth(truth.t_s)
    k = int(np.argmin(np.abs(record.t_s - (truth.t_s - 0.05))))
    np.testing.assert_allclose(delayed.R_wb, record.R_wb[k], atol=1e-12)
    assert not np.allclose(delayed.R_wb, record.R_wb[-1], atol=1e-3)


def test_imu_truth_between_steps_is_the_motion_then():
    truth = Truth(SCENE, TruthConfig(dt_s=0.005), [])
    rigidly_rotating(truth, np.array([0.0, 0.0, 0.5]))  # about a principal axis: steady
    for _ in range(4):
        truth.step({}, [0.0] * 4)
    for t in (0.0162, 0.0189, 0.02):  # between the last two steps, 1 ms before one, on one
        yaw = truth.imu_truth(t).R_wb
        np.testing.assert_allclose(yaw, rotation_zyx(0.0, 0.0, 0.5 * t), atol=2e-6)
    assert truth.has_imu_truth(0.02) and not truth.has_imu_truth(0.0201)


def test_the_imu_emulator_samples_its_own_grid_waiting_for_the_truth():
    """A sample is taken on the grid, encoded once the truth knows its time, and goes out when
    its 330 bits have crossed the wire at 115200 baud."""
    from gyrohost.simrig.imu_emu import TRUTH_WAIT_S, Bwt61Emulator, wire_time_s

    wire_s = wire_time_s(100)
    assert wire_s == pytest.approx(3 * 11 * 10 / 115200)
    asked, known = [], {"until": 0.005}
    emu = Bwt61Emulator(
        truth_source=lambda t: asked.append(t) or Truth(SCENE, TruthConfig(), []).imu_truth(0.0),
        truth_ready=lambda t: t <= known["until"],
    )
    try:
        emu.tick(0.0031)  # the grid lies on multiples of the period: nothing due yet
        emu.tick(0.0104)  # taken at 0.01, the truth not there yet: the sample waits
        assert asked == []
        known["until"] = 0.015
        emu.tick(0.0105)  # the truth is there: encoded, its bytes still on the wire
        assert (asked, emu.samples_sent) == (pytest.approx([0.01]), 0)
        assert emu.next_send_s == pytest.approx(0.01 + wire_s)
        emu.tick(0.01 + wire_s + 1e-6)  # its last byte is due: sent, showing 0.01
        assert emu.samples_sent == 1
        emu.tick(0.0203 + wire_s)  # taken at 0.02, the truth not there: waits
        emu.tick(0.02 + wire_s + TRUTH_WAIT_S - 1e-4)  # still waits
        assert emu.samples_sent == 1
        emu.tick(0.02 + wire_s + TRUTH_WAIT_S + 1e-4)  # waited its longest: sent as it stands
    finally:
        emu.close()
    assert asked == pytest.approx([0.01, 0.02])
    assert emu.samples_sent == 2


def test_a_stalled_imu_emulator_sends_the_missed_samples_and_keeps_its_grid():
    """A rig loop held up sends the samples of the stall late, together, each showing its grid
    time (the host fuses them there); a stall past the backlog loses samples, not the phase."""
    from gyrohost.simrig.imu_emu import MAX_BACKLOG_S, Bwt61Emulator

    asked = []
    emu = Bwt61Emulator(
        truth_source=lambda t: asked.append(t) or Truth(SCENE, TruthConfig(), []).imu_truth(0.0)
    )
    try:
        emu.tick(0.0)  # the grid starts here
        emu.tick(0.0455)  # held up 45.5 ms: the samples of 0.01 ... 0.04 go out now
        emu.tick(0.0455 + MAX_BACKLOG_S + 0.2)  # a stall past the backlog
    finally:
        emu.close()
    assert asked[:5] == pytest.approx([0.0, 0.01, 0.02, 0.03, 0.04])
    stall = np.array(asked[5:])
    assert len(stall) == pytest.approx(MAX_BACKLOG_S / 0.01, abs=1)  # the newest MAX_BACKLOG_S
    np.testing.assert_allclose(stall / 0.01, np.round(stall / 0.01), atol=1e-6)
    assert np.all(np.diff(stall) == pytest.approx(0.01))


def test_setup_errors_name_the_key():
    with pytest.raises(RigSetupError, match="string 's99' is not in scene dbar-gyro"):
        Truth(SCENE, TruthConfig(), [ServoConfig(name="x", id=3, pulley_radius_m=0.01,
                                                 string="s99")])  # fmt: skip
    with pytest.raises(RigSetupError, match=r"imu_frame_nodes: node\(s\) \['n9'\]"):
        Truth(SCENE, TruthConfig(imu_frame_nodes=("n1", "n9", "n2")), [])
    with pytest.raises(RigSetupError, match="on one line"):
        Truth(SCENE, TruthConfig(imu_frame_nodes=("n1", "n3", "n1")), [])


def test_a_scene_too_stiff_for_one_rk4_step_takes_substeps(tmp_path):
    """Strings 40 times stiffer (an identification's trial can be): one RK4 step of dt_s would
    blow up (the stepper refuses it), so the truth substeps within the stability limit and its
    nodes follow the same model stepped ten times finer within 1 mm (the strings' own ringing,
    at the limit, is damped faster than it is)."""
    text = Path(shipped("scene", "dbar-gyro")).read_text()
    assert "stiffness = 200.0" in text
    (tmp_path / "stiff.toml").write_text(text.replace("stiffness = 200.0", "stiffness = 8000.0"))
    scene = load_scene(tmp_path / "stiff.toml")
    truth = Truth(scene, TruthConfig(dt_s=0.005))
    omega, _ = highest_frequency(truth.model)
    assert omega * 0.005 > RK4_STABLE and omega * truth.stepper.max_dt <= RK4_STABLE
    with pytest.raises(SimulationError, match="stiff"):
        Stepper(truth.model, max_dt=0.005)
    fine = Stepper(truth.model, max_dt=truth.stepper.max_dt / 10, fast=True)
    u = truth.u.copy()
    u[0] -= 0.02  # pull the first string: the stiff strings ring
    for _ in range(20):
        x = truth.stepper.step(0.005, u)
        x_fine = fine.step(0.005, u)
    q = truth.model.layout.q
    assert np.all(np.isfinite(x)) and np.abs(x[q] - x_fine[q]).max() < 1e-3
