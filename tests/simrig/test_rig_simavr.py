"""The simulated rig with the real wheel-board firmware (simavr harness) as its wheel board.

Needs the firmware ELF and the harness (``make -C firmware check``): without them these tests
fail with the path and the make command, they never skip. The rig runs on the real clock because
the harness is paced to wall time (so are the host's heartbeats).
"""

import math
import re
import time

import numpy as np
import pytest
from control_beat import start_control_thread
from rig_host import start_rig

from gyrohost.config import ConfigError, load_rig_config, rig_config_from_dict
from gyrohost.drivers import wheelproto as wp
from gyrohost.drivers.wheelboard import WheelBoard
from gyrohost.resources import shipped
from gyrohost.simrig import simavr
from gyrohost.simrig.config import sim_config, with_sim_keys
from gyrohost.simrig.errors import FaultCommandError, RigSetupError
from gyrohost.simrig.sim import SimulatedRig

pytestmark = pytest.mark.fil

RPM = 2 * math.pi / 60
PATTERN_RAD_S = np.array([715.0, -715.0, -715.0, 715.0]) * RPM  # the paper's board pattern
SPIN_SIGN = (1, -1, 1, 1)  # wheel 1 mounted the other way round
REPLY_TIMEOUT_S = 3.0  # a loaded 2-core host can slow the harness's replies (wall clock)


def simavr_config(**wheels):
    base = load_rig_config(shipped("config", "sim-rig"))
    return with_sim_keys(base, "wheels", kind="simavr", **wheels)


@pytest.fixture(scope="module")
def binaries():
    """Fail (not skip) with the path and the make command when a binary is missing."""
    return simavr.build_binaries(simavr.firmware_build())


def wait_settled(values, target, rel: float, hold_s: float, timeout_s: float) -> float:
    """Wait until ``values()`` stays within ``rel`` of ``target`` for ``hold_s``; return when."""
    t0 = time.monotonic()
    inside_since = None
    while True:
        now = time.monotonic()
        if within(values(), target, rel):
            inside_since = now if inside_since is None else inside_since
            if now - inside_since >= hold_s:
                return inside_since - t0
        else:
            inside_since = None
        assert now - t0 < timeout_s, f"{values()} not settled at {target} +-{rel} in {timeout_s} s"
        time.sleep(0.05)


def within(measured, expected, rel: float) -> bool:
    return bool(np.all(np.abs(np.asarray(measured) - expected) <= rel * np.abs(expected)))


def test_truth_spins_follow_the_real_firmware_at_715_rpm(binaries):
    truth_target = PATTERN_RAD_S * np.array(SPIN_SIGN)
    with SimulatedRig(simavr_config(spin_sign=SPIN_SIGN), clock="real") as rig:
        assert rig.paths["wheels"] == rig.wheels.harness.pty  # the host talks to simavr directly
        with WheelBoard(rig.paths["wheels"], reply_timeout_s=REPLY_TIMEOUT_S) as board:
            start_control_thread(board)
            board.set_param("HEARTBEAT_MS", 1000)  # a loaded host may pause; not tested here
            hello = board.hello
            assert hello["n_wheels"] == 4
            board.set_speeds(PATTERN_RAD_S)
            # ramp 0.75 s, then settling to +-1 % in about 1.7 s (docs/fil.md)
            settle_s = wait_settled(rig.truth_wheel_speeds, truth_target, 0.01, 0.5, 12.0)
            t1, frames1 = time.monotonic(), rig.stats().telemetry_frames
            reports = []
            for _ in range(10):  # and stay there, next to the harness's and the firmware's own
                time.sleep(0.1)
                rig.check()
                truth = rig.truth_wheel_speeds()
                harness = np.asarray(rig.wheels.wheel_speeds_rad_s())
                reports.append(board.last_telemetry.omega_rad_s)
                assert within(truth, truth_target, 0.01), truth
                assert within(truth, harness * SPIN_SIGN, 0.01), (truth, harness)
            # one frame is the firmware's speed estimate of one moment (counts over a tick,
            # low-passed): up to 1.1 % off on a settled wheel in 120 frames; the mean of ten was
            # within 0.36 % in ten runs
            reports = np.array(reports)
            assert within(reports, PATTERN_RAD_S, 0.02), reports
            assert within(reports.mean(axis=0), PATTERN_RAD_S, 0.01), reports
            rate = (rig.stats().telemetry_frames - frames1) / (time.monotonic() - t1)
            with pytest.raises(FaultCommandError, match="need the emulator"):
                rig.command("fault wheels corrupt 3")
        stats = rig.stats()
    print(f"settled in {settle_s:.2f} s; {stats.rates_line()}; {stats.truth_line()}")
    assert rate == pytest.approx(500, rel=0.1)  # the firmware's TELEMETRY_DIV = 2 at 1 kHz
    assert not rig.wheels.harness.running()  # closing the rig stopped the harness


def test_missing_binary_names_path_and_make_command(binaries, tmp_path):
    config = simavr_config(simavr_harness=str(tmp_path / "no_harness"))
    with pytest.raises(RigSetupError, match=r"no_harness.*make -C firmware check"):
        SimulatedRig(config)


def test_gyrotens_rig_wheels_simavr_serves_the_wheel_board(binaries, tmp_path):
    proc = start_rig(tmp_path, "--wheel-board", "simavr", "--duration", "4")
    try:
        path = None
        for line in proc.stdout:
            match = re.match(r"wheels: (/dev/\S+)$", line.strip())
            if match:
                path = match[1]
                break
        assert path, proc.stderr.read()
        with WheelBoard(path, reply_timeout_s=REPLY_TIMEOUT_S) as board:
            assert board.hello["proto_version"] == wp.PROTO_VERSION
            assert board.get_param("HEARTBEAT_MS") > 0
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert re.search(r"wheels \(simavr\): firmware time [\d.]+ s .* 0 overruns", out), out


def test_simavr_wheels_refuse_stream_faults_in_the_configuration():
    with pytest.raises(ConfigError, match=r"f\.toml: key 'sim\.wheels\.faults': .*emulator"):
        sim_config(
            rig_config_from_dict(
                {"sim": {"wheels": {"kind": "simavr", "faults": {"drop_byte_prob": 0.01}}}},
                "f.toml",
            )
        )


def test_non_finite_harness_speed_is_reported_not_passed_to_the_truth():
    class Stub:  # the latest SPEED line of a harness whose motor 2 model blew up
        speed = simavr.parse_speed("SPEED 1500 1.0 2.0 nan 4.0 3")

    board = object.__new__(simavr.SimavrWheelBoard)
    board.harness = Stub()
    with pytest.raises(simavr.HarnessError, match=r"motor 2 speed is nan at firmware time 0\.0015"):
        board.wheel_speeds_rad_s()
    with pytest.raises(simavr.HarnessError, match="malformed SPEED line"):
        simavr.parse_speed("SPEED 1500 1.0 2.0")
