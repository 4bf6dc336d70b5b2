"""``gyrotens run`` on real ports refuses, before anything is opened, a configuration whose
calibration keys are still the lab-rig template's, and ports it cannot open (every one named)."""

from dataclasses import replace

from gyrohost.bringup.placeholders import find_placeholders, marked_keys
from gyrohost.bringup.serialports import access_problem
from gyrohost.cli import main
from gyrohost.resources import shipped

TEMPLATE = shipped("config", "lab-rig")


def test_run_refuses_the_template_naming_each_calibration_key(tmp_path, capsys):
    log = tmp_path / "log"
    assert main(["run", "--config", "lab-rig", "-o", str(log)]) == 2
    err = capsys.readouterr().err
    for i in (0, 1):
        assert f"servos.servo[{i}].zero_position = 0 (CALIBRATE" in err
        assert f"servos.servo[{i}].length_at_zero_m = 0.43105229381822 (CALIBRATE" in err
    assert "imu_rate_std_rad_s" not in err  # a datasheet figure is no calibration
    assert "wheel_lag_s" not in err and "servo_lag_s" not in err  # nor is the emulator's
    assert not log.exists()


def test_a_calibrated_value_or_a_removed_marker_is_no_placeholder(tmp_path):
    text = TEMPLATE.read_text()
    changed = tmp_path / "changed.toml"
    changed.write_text(text.replace("zero_position = 0 ", "zero_position = 1234 ", 1))
    keys = {p.key for p in find_placeholders(changed)}
    assert "servos.servo[0].zero_position" not in keys
    assert "servos.servo[1].zero_position" in keys
    confirmed = tmp_path / "confirmed.toml"
    confirmed.write_text(text.replace("# MEASURE", "# measured"))
    assert not [p for p in find_placeholders(confirmed) if p.marker == "MEASURE"]
    dropped = tmp_path / "dropped.toml"  # a required key left out is at its default: the same
    dropped.write_text(text.replace("zero_position = 0 ", "# zero_position = 0 ", 1))
    assert "servos.servo[0].zero_position" in {p.key for p in find_placeholders(dropped)}


def test_only_the_servos_calibration_keys_are_required():
    """The estimator's lags are marked (the simulated rig's figures) but a run starts with
    them: only the servos' zeros are required."""
    found = {p.key: p for p in find_placeholders(TEMPLATE)}
    for key in ("estimator.wheel_lag_s", "estimator.servo_lag_s"):
        assert found[key].marker == "CALIBRATE" and found[key].note.startswith("emulator value")
    required = {key for key, p in found.items() if p.required}
    assert required == {
        f"servos.servo[{i}].{k}" for i in (0, 1) for k in ("zero_position", "length_at_zero_m")
    }


def test_marked_keys_follow_tables_and_arrays_of_tables():
    text = "[a]\nx = 1  # MEASURE\n[[b.s]]\ny = 2 # CALIBRATE: zero\n[[b.s]]\ny = 3 # CALIBRATE\n"
    assert marked_keys(text) == {
        "a.x": ("MEASURE", ""),
        "b.s[0].y": ("CALIBRATE", "zero"),
        "b.s[1].y": ("CALIBRATE", ""),
    }


def test_a_port_of_a_group_you_are_not_in_says_how_to_join_it(tmp_path):
    port = tmp_path / "ttyUSB9"
    port.write_text("")
    port.chmod(0o660)
    gid = port.stat().st_gid
    problem = access_problem(str(port), uid=port.stat().st_uid + 1, groups=(gid + 1,))
    assert problem.startswith("permission denied (you are not in the group")
    assert "sudo usermod -aG" in problem and "$USER, then log out and back in" in problem
    assert access_problem(str(port), uid=port.stat().st_uid + 1, groups=(gid,)) is None
    assert access_problem(str(tmp_path / "rfcomm3")).startswith("no such device (the Bluetooth")


def test_the_run_table_of_the_configuration_sets_the_run_loops_limits(tmp_path):
    from gyrohost.config import RunTable, load_rig_config
    from gyrohost.run import RunLoop
    from gyrohost.run.request import load_schedule_arg

    config = replace(load_rig_config(shipped("config", "sim-rig")), run=RunTable(max_tilt_rad=0.5))
    loop = RunLoop(config, load_schedule_arg("paper", config.scene_path), tmp_path / "log")
    assert loop.settings.max_tilt_rad == 0.5 and loop.settings.imu_silence_s == 0.5
