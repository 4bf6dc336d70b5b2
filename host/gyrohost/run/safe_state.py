"""The safe state, where every run ends: wheels stopped, servos holding, the outcome logged.

:func:`reach_safe_state` stops all wheels and waits until every measured speed is below
``stop_threshold_rad_s`` (at most ``rampdown_timeout_s``), holds every servo at its present
position, stops the readers and closes the devices. Each step goes on whatever the one before
raised (a fault is logged as an event): the wheels are what must stop.
"""

import math

import numpy as np

from gyrohost.drivers import wheelproto as wp
from gyrohost.drivers.wheelboard import WheelBoardError
from gyrohost.sigint import SigintHandled

IGNORED_NOTE = "Ctrl-C during the safe state: ignored until it is reached"


def reach_safe_state(loop, reason: str) -> dict:
    """Ramp the wheels down, hold the servos, log the outcome; returns what was reached.

    Parameters
    ----------
    loop : RunLoop
        Its devices, readers and tick (run with ``strict=False``: faults logged, not raised).
    reason : str
        Why the run ends (logged).

    Ctrl-C is ignored meanwhile (when running in the main thread): the routine is bounded by
    ``rampdown_timeout_s`` plus the servo reply time-outs.
    """
    with SigintHandled(lambda *_: loop.event("interrupt", IGNORED_NOTE)):
        loop.phase = "rampdown"
        loop.event("safe_state", f"reason: {reason}")
        loop.ekf = None  # the estimate ends with the run; the safe state needs none
        loop.ticker.catch_up()
        loop.omega_cmd = np.zeros(wp.N_WHEELS)
        out = {"reason": reason, "wheels_stopped": None, "servos_holding": False}
        out.update(_stop_wheels(loop))
        out.update(_hold_servos(loop))
        for r in loop.readers:
            if r is not loop.servo_worker:
                r.stop()
        loop.event("safe_state", describe(out))
        _close_devices(loop)
    return out


def _stop_wheels(loop) -> dict:
    if loop.wheels is None or loop.wheels.hello is None:
        return {}  # never connected: the board's own fail-safe holds its wheels
    s = loop.settings
    try:
        loop.wheels.stop_all()
    except WheelBoardError as exc:
        loop.event("fault", f"stop_all failed ({exc}); the board's heartbeat fail-safe stops")
    start = loop.now()
    fastest, stopped = math.inf, False
    while not stopped and loop.now() - start < s.rampdown_timeout_s:
        loop.tick(strict=False)
        tel = loop.wheel_reader.latest
        if tel is None:
            continue
        fastest = float(np.max(np.abs(tel.omega_rad_s)))
        # setpoints at zero and drive stages off (the rest is coasting), or slow already
        stopped = "OUTPUTS_ENABLED" not in tel.status_names or fastest < s.stop_threshold_rad_s
    return {"wheels_stopped": stopped, "wheel_speed_max_rad_s": fastest,
            "rampdown_s": loop.now() - start}  # fmt: skip


def _hold_servos(loop) -> dict:
    if loop.servos is None:
        return {}
    if loop.servo_worker is not None:
        loop.servo_worker.stop()
    try:
        states = loop.servos.hold()
    except Exception as exc:  # report and go on: the wheels are what must stop
        loop.event("fault", f"servo hold failed: {type(exc).__name__}: {exc}")
        return {"servos_holding": False}
    held = {s.name: s.length_m for s in states}
    faults = {s.name: list(s.faults) for s in states if s.faults}
    return {"servos_holding": True, "servo_lengths_m": held, "servo_faults": faults}


def _close_devices(loop) -> None:
    for dev in (loop.wheels, loop.servos, loop.imu):  # pyserial errors are OSErrors
        if dev is not None:
            try:
                dev.close()
            except (OSError, WheelBoardError) as exc:
                loop.event("fault", f"closing {type(dev).__name__}: {exc}")


def describe(out: dict) -> str:
    """One line of what the safe state reached (the ``safe_state`` event)."""
    wheels = out.get("wheels_stopped")
    if wheels is None:
        w = "wheels never started"
    else:
        w = (
            f"wheels {'ramped down' if wheels else 'NOT ramped down'} (max "
            f"{out['wheel_speed_max_rad_s']:.2f} rad/s after {out['rampdown_s']:.2f} s)"
        )
    return f"{w}; servos {'holding' if out['servos_holding'] else 'NOT holding'}"
