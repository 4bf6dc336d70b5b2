"""The wheel board on the first day: which offsets are calibrated, their calibration, one wheel
spun slowly (docs/bring-up.md).

A board with a blank EEPROM refuses a closed-loop setpoint for a wheel whose ENC_OFFSET is still
the default (ERROR ``OFFSET_UNCALIBRATED``, docs/protocol.md "Boot state"); that refusal is the
only way the board tells a wheel's offset state, so :func:`uncalibrated_wheels` asks for it with
the smallest setpoint there is, 1 mrad/s (0.01 rpm), and sends zero right after each.
"""

import time
from collections.abc import Callable
from dataclasses import dataclass

from gyrohost.drivers import wheelproto as wp
from gyrohost.drivers.errors import DeviceError

from .devices import Target, wheel_board
from .errors import SetupInputError, WheelSetupError
from .wheel_faults import clear_reported_faults

PROBE_RAD_S = 0.001
"""The offset probe's setpoint: one unit of the wire (1 mrad/s)."""
SPIN_MAX_RAD_S = 20.0
"""Fastest first spin, rad/s: the speed the firmware's calibration is checked at
(docs/protocol.md, "Electrical zero"), 191 rpm against the run's 715."""
SPIN_MAX_S = 10.0
"""Longest first spin, s."""
TICK_S = 0.05
"""The spin's loop period, s: a fifth of the board's default HEARTBEAT_MS (250 ms)."""
SETTLE_SHARE = 0.5
"""The measured speed is the mean over this last share of the spin."""

Report = Callable[[str], None]


def uncalibrated_wheels(board) -> list[int]:
    """The wheels whose ENC_OFFSET is a default the board refuses to run closed loop with.

    ``board`` is a connected :class:`~gyrohost.drivers.wheelboard.WheelBoard`. A HEARTBEAT_LOST
    latched before the host came (the boot state) is cleared, as a run clears it.

    Raises
    ------
    WheelSetupError
        Another blocking fault is latched, or latches during the check: the board answers
        FAULT_ACTIVE to any setpoint.
    """
    latched = board.latched_faults()
    blocking = sorted(wp.BLOCKING_FAULTS.intersection(latched) - {"HEARTBEAT_LOST"})
    if blocking:
        raise WheelSetupError(
            f"offsets not checked: {', '.join(blocking)} latched (a run clears it at its start)"
        )
    board.clear_faults([f for f in latched if f == "HEARTBEAT_LOST"])
    refused = []
    for wheel in range(wp.N_WHEELS):
        speeds = [0.0] * wp.N_WHEELS
        speeds[wheel] = PROBE_RAD_S
        try:
            board.set_speeds(speeds)
        except DeviceError as exc:
            if exc.name != "OFFSET_UNCALIBRATED":  # a fault latched meanwhile: say which
                raise WheelSetupError(f"offsets not checked: {exc}") from None
            refused.append(wheel)
        board.set_speeds([0.0] * wp.N_WHEELS)  # taken or not: nothing is left commanded
    return refused


def calibrate_wheels(board, wheels: list[int], save: bool, report: Report) -> dict[int, int]:
    """CALIBRATE_ENC on each of ``wheels`` (each turns back and forth by one electrical turn),
    then PARAM_SAVE unless ``save`` is False; reports each offset. Returns wheel -> offset."""
    clear_reported_faults(board, report)
    offsets = {}
    for wheel in wheels:
        report(f"wheel {wheel}: calibrating (it turns back and forth by one electrical turn)")
        offsets[wheel] = offset = board.calibrate(wheel, save=False, timeout_s=10.0)
        report(f"wheel {wheel}: ENC_OFFSET_M{wheel} = {offset} ({offset * 360 / 65536:.1f} deg)")
    if save:
        board.save_params()
        report("saved to EEPROM")
    return offsets


def calibrate_target(target: Target, wheels: list[int], save: bool, report: Report) -> None:
    """:func:`calibrate_wheels` on the board ``target`` names (``gyrotens wheels calibrate``)."""
    config = target.rig("wheels")
    with wheel_board(config.wheelboard.port, target.hello_timeout_s) as board:
        calibrate_wheels(board, wheels, save, report)


def spin_target(target: Target, wheel: int, speed_rad_s: float, duration_s: float,
                report: Report) -> float:  # fmt: skip
    """:func:`spin_wheel` on the board ``target`` names (``gyrotens wheels spin``), stopped below
    the configuration's ``run.stop_threshold_rad_s`` within its ``run.rampdown_timeout_s``."""
    config = target.rig("wheels")
    run = config.run
    spin = Spin(wheel, speed_rad_s, duration_s, run.stop_threshold_rad_s, run.rampdown_timeout_s)
    spin.check()
    with wheel_board(config.wheelboard.port, target.hello_timeout_s) as board:
        return spin_wheel(board, spin, report)


@dataclass(frozen=True)
class Spin:
    """One slow spin of one wheel.

    Attributes
    ----------
    wheel : int
    speed_rad_s : float
        Commanded; ``|speed| <=`` :data:`SPIN_MAX_RAD_S`.
    duration_s : float
        At speed (after the board's own ramp), ``<=`` :data:`SPIN_MAX_S`.
    stop_rad_s : float
        Below this the wheel counts as stopped (the configuration's ``run.stop_threshold_rad_s``).
    rampdown_s : float
        Longest wait for the stop (``run.rampdown_timeout_s``).
    """

    wheel: int
    speed_rad_s: float
    duration_s: float
    stop_rad_s: float = 3.0
    rampdown_s: float = 5.0

    def check(self) -> None:
        """Raise :class:`SetupInputError` naming what makes this spin one to refuse."""
        problems = self.problems()
        if problems:
            raise SetupInputError("; ".join(problems))

    def problems(self) -> list[str]:
        """What makes this spin one the command refuses, one sentence each."""
        found = []
        if not 0 <= self.wheel < wp.N_WHEELS:
            found.append(f"wheel {self.wheel} is not one of 0..{wp.N_WHEELS - 1}")
        if not 0 < abs(self.speed_rad_s) <= SPIN_MAX_RAD_S:
            found.append(f"speed {self.speed_rad_s:g} rad/s: 0 < |speed| <= {SPIN_MAX_RAD_S:g}")
        if not 0 < self.duration_s <= SPIN_MAX_S:
            found.append(f"time {self.duration_s:g} s: 0 < time <= {SPIN_MAX_S:g} s")
        return found


def spin_wheel(board, spin: Spin, report: Report) -> float:
    """Spin one wheel at ``spin.speed_rad_s`` for ``spin.duration_s``, then ramp it down (also on
    Ctrl-C, which is raised again once the wheel stopped). Returns the mean measured speed over
    the last :data:`SETTLE_SHARE` of the spin, rad/s.

    Raises
    ------
    SetupInputError
        ``spin`` is refused (:meth:`Spin.problems`); nothing was sent.
    WheelSetupError
        The wheel did not stop in time.
    DeviceError
        The board refused the setpoint (its message names the fix: OFFSET_UNCALIBRATED).
    """
    spin.check()
    clear_reported_faults(board, report)
    speeds = [0.0] * wp.N_WHEELS
    speeds[spin.wheel] = spin.speed_rad_s
    try:
        board.set_speeds(speeds)
        report(f"wheel {spin.wheel}: spinning at {spin.speed_rad_s:g} rad/s, {spin.duration_s:g} s")
        measured = _mean_speed(board, spin, speeds)
        report(f"wheel {spin.wheel}: measured {measured:.2f} rad/s")
    finally:
        _ramp_down(board, spin, report)
    return measured


def _mean_speed(board, spin: Spin, speeds: list[float]) -> float:
    """Mean telemetry speed of the wheel over the last part of the spin, rad/s.

    The setpoint ``speeds`` is sent again every :data:`TICK_S`: a control frame from the thread
    that decides it is what keeps the board's heartbeat (docs/protocol.md); were this loop to
    stall, the board would ramp the wheel down by itself."""
    start = time.monotonic()
    settle_at = start + spin.duration_s * (1.0 - SETTLE_SHARE)
    samples = []
    while (now := time.monotonic()) - start < spin.duration_s:
        board.check_faults()
        board.set_speeds(speeds, confirm=False)
        time.sleep(TICK_S)
        if now >= settle_at:
            tel = board.last_telemetry
            if tel is not None:
                samples.append(tel.omega_rad_s[spin.wheel])
    if not samples:
        raise WheelSetupError(f"no wheel-board telemetry in {spin.duration_s:g} s")
    return sum(samples) / len(samples)


def _ramp_down(board, spin: Spin, report: Report) -> None:
    """STOP_ALL (the board ramps at DECEL_RAD_S2), then wait for the wheel to stop: below
    ``spin.stop_rad_s`` and its driver off (the board brakes a wheel until its encoder shows it
    at rest, and refuses a calibration meanwhile)."""
    board.stop_all()
    deadline = time.monotonic() + spin.rampdown_s
    while time.monotonic() < deadline:
        tel = board.last_telemetry
        if (
            tel is not None
            and abs(tel.omega_rad_s[spin.wheel]) < spin.stop_rad_s
            and "OUTPUTS_ENABLED" not in tel.status_names
        ):
            report(f"wheel {spin.wheel}: stopped")
            return
        time.sleep(TICK_S)
    raise WheelSetupError(
        f"wheel {spin.wheel} still above {spin.stop_rad_s:g} rad/s {spin.rampdown_s:g} s after "
        "STOP_ALL: switch the motor supply off"
    )
