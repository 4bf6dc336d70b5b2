"""A truth that differs from the model: the truth scene, the truth's IMU rotation and servo zero
offsets, the CLI flags, and the identification schedule inside the shipped rigs' limits."""

import math
from dataclasses import replace

import numpy as np
import pytest

from gyrohost.cli import main
from gyrohost.config import load_rig_config
from gyrohost.control import load_schedule
from gyrohost.drivers.imu import RATE_SCALE_RAD_S
from gyrohost.resources import resolve, shipped
from gyrohost.run.limits import check_schedule
from gyrohost.simrig.config import TruthConfig, sim_config, with_truth_scene
from gyrohost.simrig.errors import RigSetupError
from gyrohost.simrig.imu_emu import Bwt61Emulator, ImuTruth
from gyrohost.simrig.sim import SimulatedRig
from gyrohost.simrig.truth import Truth, truth_scene
from gyrotensegrity import Model, load_scene

SIM_RIG = load_rig_config(shipped("config", "sim-rig"))
SCENE_TEXT = shipped("scene", "dbar-gyro").read_text()
RADIUS = "radius = 0.031,"


def scene_file(tmp_path, name: str, *edits: tuple[str, str]):
    """The shipped D-bar scene with each ``(old, new)`` of ``edits`` replaced, as a file."""
    text = SCENE_TEXT
    for old, new in edits:
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def heavy_wheels(tmp_path_factory):
    """Truth scene whose wheels' J3 is 30 % above the shipped scene's (radius x sqrt(1.3))."""
    radius = 0.031 * math.sqrt(1.3)
    edit = (RADIUS, f"radius = {radius!r},")
    return scene_file(tmp_path_factory.mktemp("truth"), "j3", edit)


def drift_from_model(config) -> float:
    """Largest node distance, m, between the rig's truth and the model's own plant after the
    wheels spin up and the n1-n3 string is pulled 5 cm (the same inputs for both)."""
    rig_truth = Truth(truth_scene(config), sim_config(config).truth, config.servos.servo)
    model = Truth(load_scene(config.scene_path), sim_config(config).truth, config.servos.servo)
    spins = [75.0, -75.0, -75.0, 75.0]
    start = model.rest_length_m[0]
    drift = 0.0
    for k in range(300):  # 1.5 s
        pulled = start - 0.05 * min(k * model.dt_s / 1.0, 1.0)
        lengths = {1: pulled, 2: model.rest_length_m[1]}
        rig_truth.step(lengths, spins)
        model.step(lengths, spins)
        drift = max(drift, float(np.max(np.abs(rig_truth.nodes() - model.nodes()))))
    return drift


def test_truth_scene_with_heavier_wheels_drifts_from_the_model(heavy_wheels):
    nominal = drift_from_model(SIM_RIG)
    heavy = drift_from_model(with_truth_scene(SIM_RIG, heavy_wheels))
    assert nominal == 0.0  # one scene: truth and model step identically
    assert heavy > 0.01  # the truth runs the other scene: cm of difference within 1.5 s


def test_simulated_rig_runs_the_truth_scene_the_host_keeps_its_own(heavy_wheels):
    config = with_truth_scene(SIM_RIG, heavy_wheels)
    model = Model(load_scene(config.scene_path))
    with SimulatedRig(config, clock="sim") as rig:
        rig.advance(0.05)
        np.testing.assert_allclose(rig.truth.model.J3, 1.3 * model.J3, rtol=1e-12)
    assert config.scene_path == SIM_RIG.scene_path  # the host's model, estimator, planner


B12_WHEEL = "wheel = { mass = 0.050, radius = 0.031, thickness = 0.012, spin = 74.87462492 }\n\n"


@pytest.mark.parametrize(
    ("edits", "member"),
    [
        (
            [('name = "s24"', 'name = "s42"')],
            r"strings\[1\] is 's42' on \['n2', 'n4'\] in the truth",
        ),
        ([('nodes = ["n2", "n4"]', 'nodes = ["n4", "n2"]')], r"strings\[1\] is 's24' on \['n4'"),
        ([('name = "b34"', 'name = "b43"')], r"bars\[2\] is 'b43'"),
        ([('"n4"', '"n5"'), ("n4 = [", "n5 = [")], r"nodes\[3\] is 'n5' in the truth, 'n4' in"),
        (
            [(B12_WHEEL + '[[bars]]\nname = "b23"', '\n[[bars]]\nname = "b23"')],
            r"wheels\[0\] is 'b23' in the truth, 'b12' in the model \(3 wheels against 4\)",
        ),
    ],
)
def test_incompatible_truth_scene_is_refused_naming_the_member(tmp_path, edits, member):
    config = with_truth_scene(SIM_RIG, scene_file(tmp_path, "other", *edits))
    with pytest.raises(RigSetupError, match=member):
        truth_scene(config)
    with pytest.raises(RigSetupError, match=member):
        SimulatedRig(config, clock="sim")


def test_truth_scene_flags_on_the_cli(tmp_path, capsys):
    bad = scene_file(tmp_path, "bad", ('name = "s24"', 'name = "s42"'))
    assert main(["rig", "--truth-scene", str(bad), "--duration", "0.1"]) == 2
    assert "strings[1] is 's42'" in capsys.readouterr().err
    assert main(["rig", "--truth-scene", str(tmp_path / "none.toml")]) == 2
    assert "none.toml" in capsys.readouterr().err
    out = tmp_path / "run"
    assert main(["run", "--truth-scene", str(bad), "-o", str(out)]) == 2
    assert "--truth-scene is for the simulated rig: add --sim" in capsys.readouterr().err
    assert main(["run", "--sim", "--truth-scene", str(bad), "-o", str(out)]) == 2
    assert "strings[1] is 's42'" in capsys.readouterr().err


def test_servo_zero_offset_shortens_the_truths_string():
    servos = SIM_RIG.servos.servo
    offsets = (0.2, -0.1)
    config = TruthConfig(servo_zero_offset_rad=offsets)
    truth = Truth(load_scene(SIM_RIG.scene_path), config, servos)
    truth.step({s.id: s.length_at_zero_m for s in servos}, [0.0] * 4)  # the calibrated zero
    want = [
        s.length_at_zero_m - s.length_sign * s.pulley_radius_m * offset
        for s, offset in zip(servos, offsets, strict=True)
    ]
    np.testing.assert_allclose(truth.rest_length_m, want, rtol=0, atol=1e-15)


def test_imu_rotation_turns_the_sensor_about_the_body_axes():
    omega = np.array([0.0, 0.0, 1.0])  # yaw rate in body axes
    level = ImuTruth(omega_rad_s=omega)
    quiet = replace(
        sim_config(SIM_RIG).imu, gyro_noise_density_rad_s_rthz=0.0, gyro_bias_std_rad_s=0.0
    )
    emu = Bwt61Emulator(quiet, SIM_RIG.imu, rotation_deg=(3.0, 0.0, 0.0))
    try:
        frames = emu.encode_sample(level)
    finally:
        emu.close()
    rate = np.frombuffer(frames[13:19], dtype="<i2") * RATE_SCALE_RAD_S  # the 0x52 frame
    # The sensor rolled 3 deg about body x: the yaw rate shows on its y axis as sin(3 deg).
    roll = math.radians(3.0)
    np.testing.assert_allclose(rate, [0.0, math.sin(roll), math.cos(roll)], atol=2e-3)


def test_identify_schedule_is_inside_every_shipped_dbar_rigs_limits():
    schedule = load_schedule(resolve("schedule", "identify"))
    assert schedule.t[-1] <= 60.0 and sorted(schedule.names) == ["s13", "s24"]
    for name in ("sim-rig", "lab-rig"):
        config = load_rig_config(shipped("config", name))
        check_schedule(schedule, config.servos.servo, config.run)
    # wheel speed steps: every wheel at three speeds, the pattern kept, the start the scene's
    assert schedule.wheels == ("b12", "b23", "b34", "b41")
    spins = schedule.wheel_speed
    np.testing.assert_allclose(spins[0], [74.87462492, -74.87462492, -74.87462492, 74.87462492])
    assert len(np.unique(np.round(np.abs(spins[:, 0]), 3))) == 3
    np.testing.assert_allclose(spins * np.sign(spins[0]), np.abs(spins))
    s13 = schedule.rest_length[:, schedule.names.index("s13")]
    dt = np.diff(schedule.t)
    held = np.isclose(np.diff(s13), 0.0)
    rates = {round(float(v), 3) for v in np.abs(np.diff(s13) / dt)[~held]}
    assert len(rates) >= 4  # pulls at several rates
    assert dt[held].sum() >= 10.0  # rests and holds: at least 10 s of them
    assert s13.min() < s13[0] - 0.05 and s13.max() > s13[0] + 0.01  # amplitudes both ways


def test_identify_schedule_is_at_rest_where_the_fit_starts_a_segment():
    """``gyrotens identify`` cuts a log into 4 s segments (its default) from the lead-in, which
    a run holds for ``lead_in_s`` before the schedule: each later segment starts from the IMU
    and the previous segment's shape, which is right only with the structure at rest
    (docs/identification.md), so no string moves from 0.45 s before an edge to 0.2 s after it,
    and the wheels are still there too."""
    from gyrohost.run.settings import RunSettings

    schedule = load_schedule(resolve("schedule", "identify"))
    lead_s, segment_s = RunSettings().lead_in_s, 4.0
    edges = np.arange(segment_s, schedule.t_end + lead_s, segment_s) - lead_s
    assert len(edges) >= 4
    for edge in edges:
        t = np.linspace(edge - 0.45, min(edge + 0.2, schedule.t_end), 50)
        lengths = np.array([schedule(x) for x in t])
        speeds = np.array([schedule.wheel_speeds(x) for x in t])
        assert np.ptp(lengths, axis=0).max() < 1e-9, f"a string moves at {edge:g} s"
        assert np.ptp(speeds, axis=0).max() < 1e-9, f"a wheel speed changes at {edge:g} s"
