"""``gyrotens doctor`` against the simulated rig's ptys: every check passing, then each failing
on purpose; exit status 1 on a FAIL, 0 with WARNs only, 2 for a configuration it cannot read."""

import re
import subprocess
import sys

from bringup_rig import config_text

from gyrohost.bringup.doctor import Windows, run_checks
from gyrohost.cli import main
from gyrohost.config import load_rig_config
from gyrohost.drivers import wheelproto as wp

FAST = Windows(imu_s=0.5, hello_s=1.0, imu_rate_tolerance=0.9)
"""Short waits; any IMU rate from 10 to 190 Hz passes for 100 Hz: the emulators share a loaded
machine (a configured 20 Hz still fails)."""
FAST_ARGS = ["--imu-window", "0.5", "--hello-timeout", "1.0", "--imu-rate-tolerance", "0.9"]


def checks(tmp_path, text, sys_root=None):
    path = tmp_path / "rig.toml"
    path.write_text(text)
    extra = {} if sys_root is None else {"sys_root": sys_root}
    return {c.name: c for c in run_checks(load_rig_config(path), windows=FAST, **extra)}


def test_doctor_passes_a_configuration_of_the_simulated_rig(tmp_path, rig_ports, capsys):
    path = tmp_path / "rig.toml"
    path.write_text(config_text("sim-rig", rig_ports))
    argv = ["doctor", "--config", str(path), *FAST_ARGS]
    status = main(argv)
    out = capsys.readouterr().out.splitlines()
    assert status == 0 and all(line.startswith("PASS") for line in out), out
    text = "\n".join(out)
    assert f"wheel board firmware 1.0, protocol v{wp.PROTO_VERSION}, 4 wheels" in text
    assert "PASS  wheel offsets: all 4 calibrated" in text
    assert "answered at 1000000 baud: ID 1 MX-12W, ID 2 MX-12W" in text
    assert "PASS  imu: BWT61CL frames at" in text


def test_doctor_fails_each_check_on_purpose(tmp_path, rig_ports, capsys):
    wrong = dict(rig_ports, wheels=rig_ports["imu"])  # no HELLO reply from the IMU's pty
    text = config_text(
        "sim-rig",
        wrong,
        rate=("rate_hz = 100", "rate_hz = 20"),  # measured 100 Hz, and 20 Hz needs 9600 baud
        servo=("id = 2", "id = 7"),
        limit=("min_length_m = 0.40", "min_length_m = 0.44"),  # the scene starts s24 at 0.431
    )
    found = checks(tmp_path, text)
    assert not found["imu"].ok and "configured imu.rate_hz = 20" in found["imu"].detail
    assert not found["wheel board"].ok and "no HELLO reply in 1 s" in found["wheel board"].detail
    assert not found["servos"].ok and "no reply from ID 7" in found["servos"].detail
    limits = found["limits"]
    assert not limits.ok and "imu.rate_hz = 20 needs imu.baud = 9600, not 115200" in limits.detail
    assert "servos.servo[1]: the scene starts string s24 at 0.4311 m" in limits.detail
    path = tmp_path / "bad.toml"
    path.write_text(text)
    argv = ["doctor", "--config", str(path), *FAST_ARGS]
    status = main(argv)
    out = capsys.readouterr().out
    assert status == 1 and out.count("FAIL") == 4, out


def test_doctor_names_placeholders_missing_ports_and_the_latency_timer(tmp_path, rig_ports):
    missing = dict(rig_ports, wheels=str(tmp_path / "ttyACM9"))
    path = tmp_path / "rig.toml"
    path.write_text(config_text("lab-rig", missing))
    lines = [c.line() for c in run_checks(load_rig_config(path), windows=FAST)]
    assert "FAIL  placeholder: servos.servo[0].zero_position = 0 (CALIBRATE" in "\n".join(lines)
    for key in ("wheel_lag_s", "servo_lag_s"):  # the simulated rig's figures: a run takes them
        assert any(
            line.startswith(f"WARN  placeholder: estimator.{key} = 0.05 (CALIBRATE: emulator")
            for line in lines
        ), lines
    found = {c.name: c for c in run_checks(load_rig_config(path), windows=FAST)}
    port_check = found[f"wheelboard.port {tmp_path / 'ttyACM9'}"]
    assert not port_check.ok and port_check.detail.startswith("no such device")
    assert "wheel board" not in found  # nothing to identify
    sysfs = tmp_path / "sys"
    timer = sysfs / "bus/usb-serial/devices" / rig_ports["servos"].rsplit("/", 1)[1]
    timer.mkdir(parents=True)
    (timer / "latency_timer").write_text("16\n")
    found = checks(tmp_path, config_text("sim-rig", rig_ports), sys_root=sysfs)
    latency = found["servos latency timer"]
    assert not latency.ok and f"echo 1 | sudo tee {timer / 'latency_timer'}" in latency.detail
    (timer / "latency_timer").write_text("1\n")
    found = checks(tmp_path, config_text("sim-rig", rig_ports), sys_root=sysfs)
    assert found["servos latency timer"].ok


def test_doctor_checks_the_rfcomm_binding_of_the_imu(tmp_path, rig_ports):
    text = config_text("sim-rig", dict(rig_ports, imu="/dev/rfcomm7"))
    sysfs = tmp_path / "sys"
    found = checks(tmp_path, text, sys_root=sysfs)
    assert not found["imu rfcomm"].ok and "sudo rfcomm bind 7 " in found["imu rfcomm"].detail
    assert "imu.port /dev/rfcomm7" not in found  # the one failure of an unbound IMU
    (sysfs / "class/tty/rfcomm7").mkdir(parents=True)
    found = checks(tmp_path, text, sys_root=sysfs)
    assert found["imu rfcomm"].ok and found["imu rfcomm"].detail == "rfcomm7 bound"
    assert not found["imu.port /dev/rfcomm7"].ok  # bound here in a fake sysfs only


HOLD = (
    "import sys\nfrom gyrohost.drivers.portlock import PortClaim\n"
    "claim = PortClaim(sys.argv[1])\nprint('held', flush=True)\nsys.stdin.read()\n"
)


def test_doctor_names_the_process_holding_a_port_and_sends_it_nothing(tmp_path, rig_ports):
    """A run under way holds the wheel board's port: the doctor's check fails naming it (its
    HELLO would have reached the board in the middle of the run)."""
    holder = subprocess.Popen([sys.executable, "-c", HOLD, rig_ports["wheels"]],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)  # fmt: skip
    try:
        assert holder.stdout.readline() == "held\n"
        found = checks(tmp_path, config_text("sim-rig", rig_ports))
    finally:
        holder.communicate("", timeout=30)
    board = found["wheel board"]
    assert not board.ok and f"is in use by PID {holder.pid} (" in board.detail, board
    assert found["imu"].ok and found["servos"].ok


def test_doctor_passes_a_completed_lab_rig_with_warnings_only(tmp_path, rig_ports, capsys):
    """Every CALIBRATE key the run refuses filled in (the servos' zeros): the datasheet figures
    and the lags stay WARN, and the exit status is 0."""
    text = config_text("lab-rig", rig_ports)
    text = re.sub(r"(zero_position = 0 +)# CALIBRATE.*", r"\1", text)
    text = re.sub(r"(length_at_zero_m = \S+ +)# CALIBRATE.*", r"\1", text)
    path = tmp_path / "lab.toml"
    path.write_text(text)
    status = main(["doctor", "--config", str(path), *FAST_ARGS])
    out = capsys.readouterr().out.splitlines()
    assert status == 0, out
    assert not [line for line in out if line.startswith("FAIL")], out
    assert any(line.startswith("WARN  placeholder: estimator.wheel_lag_s") for line in out)


def test_doctor_without_a_configuration_is_bad_usage(tmp_path, capsys):
    assert main(["doctor", "--config", str(tmp_path / "none.toml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("gyrotens doctor: error: "), err
