"""The run's rule for faults latched on the wheel board before it starts.

A board that booted without a host latches HEARTBEAT_LOST; one with a blank EEPROM latches
PARAMS_DEFAULTED; an earlier session may have left an encoder, stall or runaway fault. The run
reports each latched fault to the user by name and text, and then clears exactly those it
reported (CLEAR_FAULTS carries their bits): a fault that latches in between stays latched and
shows in the run's checks. Clearing PARAMS_DEFAULTED does not make default ENC_OFFSETs usable:
the board refuses closed-loop setpoints until the offsets are calibrated or set
(``gyrotens wheels calibrate``).
"""

from __future__ import annotations

from collections.abc import Callable

from gyrohost.drivers import wheelproto as wp


def clear_reported_faults(board, report: Callable[[str], None]) -> list[str]:
    """Report the faults of the board's next telemetry frame, then clear them; returns them.

    Parameters
    ----------
    board : WheelBoard
        Connected (telemetry running).
    report : callable(str)
        Shows one line to the user (and logs it); called for each fault, then once naming
        those cleared.
    """
    latched = board.latched_faults()
    for name in latched:
        report(f"wheel board: {name} latched at connect: {wp.fault_text(name)}")
    cleared = board.clear_faults(latched)
    if cleared:
        report(f"wheel board: cleared {', '.join(cleared)}")
    return cleared
