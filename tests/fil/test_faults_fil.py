"""Firmware in the loop: sensor and motion faults, and the electrical zero found by CALIBRATE_ENC.

The real ELF in the simavr harness with a dead, frozen or weak-magnet encoder, a blocked rotor and
a wrong electrical offset: each fault latches with its named bit and the drivers go off; a board
with default offsets refuses closed-loop setpoints until CALIBRATE_ENC (or PARAM_SET) sets them.
Delays are measured on the device's own time stamps (telemetry ``t_us``), never on the wall clock.
"""

from __future__ import annotations

import math
import time

import pytest
from control_beat import start_control_thread
from filharness import Harness, firmware_elf, set_offsets

from gyrohost.drivers import wheelproto as wp
from gyrohost.drivers.errors import DeviceError
from gyrohost.drivers.wheelboard import WheelBoard

pytestmark = pytest.mark.fil

TARGET_RAD_S = 459 * 2 * math.pi / 60  # the dead-encoder case: 459 rpm
REPLY_TIMEOUT_S = 3.0  # wall clock: a loaded host can slow the simulation
LATCH_MAX_S = 0.020  # sensor faults latch within 20 ms


def open_board(h: Harness, offsets: bool = True) -> WheelBoard:
    board = WheelBoard(h.pty, reply_timeout_s=REPLY_TIMEOUT_S)
    board.connect()
    start_control_thread(board)
    board.set_param("HEARTBEAT_MS", 1000)  # a loaded host may pause; the heartbeat is not tested
    board.clear_faults(board.latched_faults())  # the boot's HEARTBEAT_LOST / PARAMS_DEFAULTED
    if offsets:
        set_offsets(board)
    return board


def telemetry_until(board: WheelBoard, done, timeout_s: float = 10.0) -> list[wp.Telemetry]:
    """Telemetry from now until ``done(sample)`` holds (that sample included)."""
    while not board.telemetry.empty():
        board.telemetry.get_nowait()
    out: list[wp.Telemetry] = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            sample = board.telemetry.get(timeout=0.05)
        except Exception:  # queue.Empty
            continue
        out.append(sample)
        if done(sample):
            return out
    raise AssertionError(f"condition not reached in {timeout_s} s; last {out[-1:]}")


def first(samples: list[wp.Telemetry], cond) -> wp.Telemetry:
    return next(s for s in samples if cond(s))


def test_dead_encoder_reading_zero_latches_within_20_ms_and_disables_the_wheel():
    """MISO stuck low: words 0x0000 with valid parity and no error flag. The wheel's speed
    estimate drops at once (the angle stops); the fault latches within 20 ms of that, and the
    drive goes to 0 (it was held at full drive with faults 0 before)."""
    with Harness(firmware_elf()) as h:
        board = open_board(h)
        try:
            board.set_speeds([TARGET_RAD_S, 0.0, 0.0, 0.0])
            telemetry_until(board, lambda s: s.omega_rad_s[0] > 0.97 * TARGET_RAD_S)
            assert h.command("fault 0 low") == "OK fault 0 low"
            samples = telemetry_until(board, lambda s: "ENCODER_M0" in s.fault_names)
            drop = first(samples, lambda s: s.omega_rad_s[0] < 0.9 * TARGET_RAD_S)
            latched = samples[-1]
            assert (latched.t_us - drop.t_us) * 1e-6 <= LATCH_MAX_S, (drop, latched)
            assert "ENC_STUCK" in latched.fault_names or "ENC_DIAG" in latched.fault_names
            after = telemetry_until(board, lambda s: True)
            assert after[-1].drive[0] == 0.0
            with pytest.raises(DeviceError) as err:
                board.set_speeds([TARGET_RAD_S, 0.0, 0.0, 0.0])
            assert err.value.name == "FAULT_ACTIVE"
        finally:
            board.close()


def test_frozen_valid_word_while_driven_latches_stall():
    """A valid angle word that stops changing (diagnostics fine) while the loop drives the wheel:
    the board cannot tell it from a blocked rotor, so STALL latches after MOTION_FAULT_MS of
    saturated drive and every wheel is disabled."""
    with Harness(firmware_elf()) as h:
        board = open_board(h)
        try:
            fault_ms = board.get_param("MOTION_FAULT_MS")
            board.set_speeds([0.0, TARGET_RAD_S, 0.0, 0.0])
            telemetry_until(board, lambda s: s.omega_rad_s[1] > 0.97 * TARGET_RAD_S)
            assert h.command("fault 1 frozen") == "OK fault 1 frozen"
            samples = telemetry_until(board, lambda s: "STALL" in s.fault_names)
            drop = first(samples, lambda s: s.omega_rad_s[1] < 0.9 * TARGET_RAD_S)
            latched = samples[-1]
            assert latched.fault_names == ["STALL"]
            # the filtered speed falls below STALL_SPEED about 30 ms after the drop, then
            # MOTION_FAULT_MS of saturated drive
            assert (latched.t_us - drop.t_us) * 1e-6 <= fault_ms * 1e-3 + 0.040
        finally:
            board.close()


def test_weak_magnet_in_the_diagnostics_register_latches_enc_diag_at_rest():
    """The diagnostics register is read round robin even with every wheel at rest."""
    with Harness(firmware_elf()) as h:
        board = open_board(h)
        try:
            assert h.command("fault 3 weak") == "OK fault 3 weak"
            latched = telemetry_until(board, lambda s: "ENCODER_M3" in s.fault_names)[-1]
            assert set(latched.fault_names) == {"ENCODER_M3", "ENC_DIAG"}
            with pytest.raises(DeviceError) as err:
                board.set_speeds([0.0, 0.0, 0.0, 1.0])
            assert err.value.name == "FAULT_ACTIVE"
            assert h.command("clear 3") == "OK clear 3"
            assert board.clear_faults(["ENCODER_M3", "ENC_DIAG"]) == ["ENCODER_M3", "ENC_DIAG"]
            time.sleep(0.2)
            assert board.latched_faults() == []
        finally:
            board.close()


def test_blocked_rotor_latches_stall_and_disables_every_wheel():
    """A load torque far above the motor's blocks wheel 2 (turned first: the harness's noiseless
    encoder at rest on angle 0 under drive would read as a stuck 0x0000 word)."""
    with Harness(firmware_elf()) as h:
        board = open_board(h)
        try:
            board.set_speeds([5.0, 5.0, 5.0, 5.0])
            telemetry_until(board, lambda s: s.omega_rad_s[2] > 4.0)
            assert h.command("load 2 0.5").startswith("OK")
            latched = telemetry_until(board, lambda s: "STALL" in s.fault_names)[-1]
            assert "RUNAWAY" not in latched.fault_names
            after = telemetry_until(board, lambda s: True)[-1]
            assert after.drive == (0.0, 0.0, 0.0, 0.0)
            assert "OUTPUTS_ENABLED" not in after.status_names
        finally:
            board.close()


def test_wrong_electrical_offset_latches_runaway():
    """ENC_OFFSET 0 on a motor whose electrical zero is at 150 degrees: +20 rad/s commanded, the
    wheel turns backwards (it reached -124 rad/s with faults 0 before); RUNAWAY latches and the
    drivers go off while the wheel is still slow."""
    with Harness(firmware_elf(), args=["--elec-offset", "150"]) as h:
        board = open_board(h)
        try:
            board.set_speeds([20.0, 0.0, 0.0, 0.0])
            samples = telemetry_until(board, lambda s: "RUNAWAY" in s.fault_names)
            assert min(s.omega_rad_s[0] for s in samples) > -40.0
            after = telemetry_until(board, lambda s: True)[-1]
            assert after.drive[0] == 0.0
        finally:
            board.close()


def test_defaulted_offsets_block_setpoints_until_calibrated_then_the_loop_works():
    """A blank EEPROM: closed-loop setpoints refused with OFFSET_UNCALIBRATED naming the wheel;
    CALIBRATE_ENC on a motor with its electrical zero at 150 degrees finds the offset, and +20 rad/s
    is then reached without a fault."""
    with Harness(firmware_elf(), args=["--elec-offset", "150"]) as h:
        board = open_board(h, offsets=False)
        try:
            board.set_speeds([0.0, 0.0, 0.0, 0.0])  # zero is always accepted
            with pytest.raises(DeviceError) as err:
                board.set_speeds([20.0, 0.0, 0.0, 0.0])
            assert (err.value.name, err.value.detail) == ("OFFSET_UNCALIBRATED", 0)
            offset = board.calibrate(0, save=False, timeout_s=20.0)  # 2.8 s simulated
            # 150 degrees electrical at encoder zero: cmt_elec_angle = mech * 4 pp - offset reads
            # 0 where the rotor's electrical angle is 0, i.e. offset = -150 deg = 210 deg.
            expected = round(210 / 360 * 65536)
            assert abs((offset - expected + 32768) % 65536 - 32768) < 65536 * 5 / 360
            board.set_speeds([20.0, 0.0, 0.0, 0.0])
            telemetry_until(board, lambda s: abs(s.omega_rad_s[0] - 20.0) < 0.5)
            time.sleep(0.3)
            assert board.latched_faults() == []
            with pytest.raises(DeviceError) as err:
                board.set_speeds([20.0, 20.0, 0.0, 0.0])
            assert (err.value.name, err.value.detail) == ("OFFSET_UNCALIBRATED", 1)
        finally:
            board.close()
