"""What ``gyrotens identify`` says about a log it should not be trusted with (a run that
stopped before its schedule ended, a simulated rig whose truth did not keep real time) and
about noise keys the lab has not measured."""

import pytest

from gyrohost.cli import main
from gyrohost.ident.logs import log_warnings
from gyrohost.run.log import RunLog
from gyrohost.simrig.stats import LATE_SHARE_MAX, RigStats


def write_log(folder, summary, events):
    """A log folder with only ``meta.json`` (``summary``) and its ``events`` stream."""
    with RunLog(folder, {}) as log:
        stream = log.stream("events", ["t_s", "kind", "message"], ("kind", "message"))
        for row in events:
            stream.write(*row)
        log.update_meta(summary=summary)
    return folder


PHASES = [(0.1, "phase", "hold"), (1.0, "phase", "lead_in"), (3.0, "phase", "schedule")]
KEPT = {"kept": True, "late_share": 0.003, "max_lag_s": 0.0075, "slipped_s": 0.0}
LATE = {"kept": False, "late_share": 0.6, "max_lag_s": 0.25, "slipped_s": 0.21}


def test_a_completed_real_time_run_has_nothing_to_say(tmp_path):
    log = write_log(tmp_path / "log", {"completed": True, "rig_real_time": KEPT}, PHASES)
    assert log_warnings(log) == []


def test_a_run_stopped_early_says_how_far_into_its_schedule_and_why(tmp_path):
    reason = "EstimatorProcessError: the estimate is 1.004 s behind the loop"
    events = [*PHASES, (3.5, "end", reason), (3.6, "phase", "rampdown")]
    summary = {"completed": False, "reason": reason, "rig_real_time": KEPT}
    (warning,) = log_warnings(write_log(tmp_path / "log", summary, events))
    assert "stopped 0.5 s into its schedule" in warning and reason in warning, warning


def test_a_run_stopped_before_its_schedule_says_so(tmp_path):
    summary = {"completed": False, "reason": "interrupted"}
    (warning,) = log_warnings(write_log(tmp_path / "log", summary, PHASES[:2]))
    assert "stopped before its schedule began (interrupted)" in warning, warning


def test_a_truth_late_on_the_simulated_rig_is_named_with_its_figures(tmp_path, capsys):
    log = write_log(tmp_path / "log", {"completed": True, "rig_real_time": LATE}, PHASES)
    (warning,) = log_warnings(log)
    assert "did not keep real time (60 % of its steps late, up to 250 ms" in warning, warning
    # the command says it before it reads the streams (which this log does not have)
    assert main(["identify", str(log), "-o", str(tmp_path / "i.toml")]) != 0
    assert warning in capsys.readouterr().err


def test_a_log_without_a_summary_is_named(tmp_path):
    (warning,) = log_warnings(write_log(tmp_path / "log", None, PHASES))
    assert "no summary" in warning, warning


def stats(late_steps: int, slipped_s: float = 0.0) -> RigStats:
    return RigStats(10.0, 1000, 500, 800, 2000, late_steps, 0.005, 1.0, 0.02, slipped_s, 4.0)


@pytest.mark.parametrize(
    ("late_steps", "slipped_s", "kept"),
    [(0, 0.0, True), (int(LATE_SHARE_MAX * 2000), 0.0, True),
     (int(LATE_SHARE_MAX * 2000) + 1, 0.0, False), (0, 0.01, False)],
)  # fmt: skip
def test_real_time_is_kept_with_few_late_steps_and_no_slip(late_steps, slipped_s, kept):
    figures = stats(late_steps, slipped_s).real_time()
    assert figures["kept"] is kept
    assert figures["late_share"] == late_steps / 2000


def test_noise_keys_left_at_the_templates_datasheet_values_are_named(tmp_path, capsys):
    """The fit weighs each sensor by the estimator's noise keys: a copy of the lab-rig
    template that still has them says so, one line per key, and a measured one (its marker
    removed) does not."""
    from gyrohost.ident.noise import KEYS
    from gyrohost.resources import resolve

    log = write_log(tmp_path / "log", {"completed": True}, PHASES)
    text = resolve("config", "lab-rig").read_text()
    config = tmp_path / "my-rig.toml"
    config.write_text(text)
    argv = ["identify", str(log), "-o", str(tmp_path / "i.toml"), "--config", str(config)]
    assert main(argv) != 0  # the log has no streams, after the warnings
    err = capsys.readouterr().err
    for key in KEYS:
        assert f"estimator.{key} is still the template's datasheet value" in err, key
    measured = "\n".join(
        line.split("#")[0] if line.startswith("imu_rate_std_rad_s") else line
        for line in text.splitlines()
    )
    config.write_text(measured)
    main(argv)
    err = capsys.readouterr().err
    assert "imu_rate_std_rad_s is still" not in err and "imu_angle_std_rad is still" in err
