"""The safe state, where every run ends: wheels stopped, servos holding, the outcome logged.

:func:`reach_safe_state` runs its steps in order: stop the wheels (``STOP_ALL``, then wait until
the board has switched its drives off or every measured speed is below ``stop_threshold_rad_s``,
at most ``rampdown_timeout_s``), hold the servos (and read each one back), stop the readers,
close the devices. Each step is attempted whatever the one before raised (``OSError`` and
``serial.SerialException``, a driver fault, ``termios.error``, anything): the step's failure is
logged as a ``fault`` event and kept in ``steps``, with what was reached, so the summary and the
terminal say what happened. Interrupting signals are logged and ignored meanwhile.
"""

import signal
import time
from functools import partial

import numpy as np

from gyrohost.drivers import wheelproto as wp
from gyrohost.run.devices import failure_text
from gyrohost.sigint import InterruptsHandled

SPEED_SETTLED_US = 50_000
"""Board time since boot before its speeds count (a board that reset mid-run): the firmware's
8 ms speed low-pass starts from zero at a boot and is within 0.2 % of the speed after 50 ms."""
HOLD_TOLERANCE_STEPS = 32
"""A servo holds when its torque is on and its goal is within this of its present position."""


def ignore_interrupts(loop, what: str) -> InterruptsHandled:
    """Context: an interrupting signal is ignored and logged as an ``interrupt`` event by the
    loop's next event (``loop.heard``): the handler itself writes nothing, since the signal may
    land while the loop is inside a write of that same file (a reentrant call, which raised)."""

    def note(signum, frame):
        loop.heard.append(f"{signal.Signals(signum).name} during {what}: ignored")

    return InterruptsHandled(note)


def reach_safe_state(loop, reason: str) -> dict:
    """Ramp the wheels down, hold the servos, close the devices; returns what was reached.

    Parameters
    ----------
    loop : RunLoop
        Its devices, readers and tick (run with ``strict=False``: faults logged, not raised).
    reason : str
        Why the run ends (logged).

    Returns
    -------
    dict
        ``reason``; ``wheels_stopped`` (None: never connected) and ``wheels`` (what the wheels
        did, one line), ``wheel_speeds_at_exit_rad_s`` (the last telemetry) and its age
        ``wheel_telemetry_age_s``, ``wheel_board_resets``; ``servos_holding`` and ``servos``
        (per servo: ``holding``, ``length_m``, ``faults``, ``why`` when not holding); ``steps``
        (``step``, ``ok``, ``detail`` each).

    Interrupting signals are ignored meanwhile (when running in the main thread): the routine is
    bounded by ``rampdown_timeout_s`` plus the devices' reply time-outs.
    """
    with ignore_interrupts(loop, "the safe state"):
        loop.phase = "rampdown"
        loop.event("safe_state", f"reason: {reason}")
        loop.ekf = None  # the estimate ends with the run; the safe state needs none
        loop.ticker.catch_up()
        loop.omega_cmd = np.zeros(wp.N_WHEELS)
        out = {"reason": reason, "wheels_stopped": None, "servos_holding": False, "steps": []}
        for name, step in STEPS:
            attempt(loop, out, name, partial(step, loop, out))
        loop.event("safe_state", describe(out))
    return out


def attempt(loop, out: dict, name: str, step) -> None:
    """Run ``step() -> (ok, detail)``; whatever it raises becomes its failed outcome. The
    outcome goes to ``out["steps"]`` and, failed, to a ``fault`` event of ``loop``."""
    try:
        ok, detail = step()
    except Exception as exc:  # the next step must run whatever this one raised
        ok, detail = False, failure_text(exc)
    out["steps"].append({"step": name, "ok": ok, "detail": detail})
    if not ok:
        loop.event("fault", f"safe state: {name} failed: {detail}")


def _stop_wheels(loop, out: dict) -> tuple[bool, str]:
    if loop.wheels is None or loop.wheels.hello is None:
        out["wheels"] = "wheels never started (board not connected)"
        return True, out["wheels"]
    s = loop.settings
    reader = loop.wheel_reader
    stop_ns = time.monotonic_ns()
    try:
        loop.wheels.stop_all()
        sent = None
    except Exception as exc:  # pyserial's errors are OSErrors; a timed-out ACK, anything
        sent = f"STOP_ALL failed ({failure_text(exc)})"
    start = loop.now()
    ramped = False
    while not ramped and loop.now() - start < s.rampdown_timeout_s:
        loop.tick(strict=False)
        tel = reader.latest
        if tel is not None and reader.latest_ns > stop_ns and tel.t_us >= SPEED_SETTLED_US:
            # setpoints at zero and drive stages off (the rest is coasting), or slow already
            fastest = float(np.max(np.abs(tel.omega_rad_s)))
            ramped = "OUTPUTS_ENABLED" not in tel.status_names or fastest < s.stop_threshold_rad_s
    out["rampdown_s"] = loop.now() - start
    out["wheel_board_resets"] = [what for _, what in reader.reboots]
    wheels, ok = _wheels_at_exit(loop, out, stop_ns, ramped)
    out["wheels"] = wheels if sent is None else f"{sent}; {wheels}"
    return ok and sent is None, out["wheels"]


def _wheels_at_exit(loop, out: dict, stop_ns: int, ramped: bool) -> tuple[str, bool]:
    """What the last telemetry says of the wheels (never inferred from what was commanded)."""
    s, reader = loop.settings, loop.wheel_reader
    tel, tel_ns = reader.latest, reader.latest_ns
    out["wheels_stopped"] = False
    alive = "if the board is alive, its heartbeat fail-safe stops the wheels"
    if tel is None:
        out["wheel_speeds_at_exit_rad_s"] = None
        return f"wheel speeds unknown: no telemetry in the run; {alive}", False
    speeds = [float(w) for w in tel.omega_rad_s]
    fastest = max(abs(w) for w in speeds)
    out["wheel_speeds_at_exit_rad_s"] = speeds
    out["wheel_telemetry_age_s"] = (time.monotonic_ns() - tel_ns) / 1e9
    out["wheel_speed_max_rad_s"] = fastest
    if tel_ns <= stop_ns:
        return (
            f"wheel speeds unknown: no telemetry since the safe state began (the last, "
            f"{out['wheel_telemetry_age_s']:.1f} s old: max {fastest:.1f} rad/s); {alive}"
        ), False
    measured = f"max {fastest:.2f} rad/s measured at exit"
    if fastest < s.stop_threshold_rad_s:
        out["wheels_stopped"] = True
        return f"wheels stopped ({measured})", True
    if reader.reboots:
        t_reset = (reader.reboots[-1][0] - loop.ticker.t0_ns) / 1e9
        return (
            f"wheels NOT stopped: the wheel board reset at t = {t_reset:.2f} s and left them "
            f"coasting ({measured})"
        ), False
    if ramped:
        out["wheels_stopped"] = True
        return f"wheels ramped down by the board, drives off, coasting ({measured})", True
    return f"wheels NOT ramped down after {out['rampdown_s']:.1f} s ({measured})", False


def _hold_servos(loop, out: dict) -> tuple[bool, str]:
    if loop.servos is None:
        return True, "never connected"
    if loop.servo_worker is not None:
        loop.servo_worker.stop()
    failed = None
    try:
        loop.servos.hold()
    except Exception as exc:  # each servo is read back below: some may hold all the same
        failed = f"hold: {failure_text(exc)}"
    servos = {servo.name: _read_hold(loop.servos, servo.name) for servo in loop.config.servos.servo}
    out["servos"] = servos
    out["servos_holding"] = all(s["holding"] for s in servos.values())
    lines = [f"{name} {_servo_line(s)}" for name, s in servos.items()]
    detail = "; ".join(([failed] if failed else []) + lines)
    return out["servos_holding"], detail


def _read_hold(bus, name: str) -> dict:
    try:
        torque, goal, state = bus.read_hold(name)
    except Exception as exc:
        return {"holding": False, "why": f"no read-back: {failure_text(exc)}"}
    off = goal - state.position_steps
    out = {"holding": torque and abs(off) <= HOLD_TOLERANCE_STEPS, "length_m": state.length_m,
           "faults": list(state.faults)}  # fmt: skip
    if not torque:
        out["why"] = "torque off"
    elif not out["holding"]:
        out["why"] = f"goal {off:+d} steps from its position: moving, not holding"
    return out


def _servo_line(s: dict) -> str:
    if not s["holding"]:
        return f"NOT holding ({s['why']})"
    faults = f", faults: {', '.join(s['faults'])}" if s["faults"] else ""
    return f"holding at {s['length_m']:.4f} m{faults}"


def _stop_readers(loop, out: dict) -> tuple[bool, str]:
    alive = []
    for r in loop.readers:
        if r is not loop.servo_worker:
            r.stop()
        if r.alive:
            alive.append(r.name)
    return not alive, f"still running: {', '.join(alive)}" if alive else "stopped"


def _close_devices(loop, out: dict) -> tuple[bool, str]:
    failed = []
    for dev in (loop.wheels, loop.servos, loop.imu):
        if dev is not None:
            try:
                dev.close()
            except Exception as exc:  # a device already gone (pyserial errors are OSErrors)
                failed.append(f"{type(dev).__name__}: {failure_text(exc)}")
    return not failed, "; ".join(failed) or "closed"


STEPS = (
    ("stop wheels", _stop_wheels),
    ("hold servos", _hold_servos),
    ("stop readers", _stop_readers),
    ("close devices", _close_devices),
)
"""The safe state's steps, in order: ``step(loop, out) -> (ok, detail)``."""


def describe(out: dict) -> str:
    """One line of what the safe state reached (the ``safe_state`` event)."""
    w = out.get("wheels", "wheels: no outcome")
    if "servos" not in out:
        return f"{w}; servos never connected"
    return f"{w}; servos {'holding' if out['servos_holding'] else 'NOT all holding'}"


def failed_steps(out: dict) -> list[str]:
    """One line per failed step of the safe state (for the terminal)."""
    return [f"{s['step']} failed: {s['detail']}" for s in out.get("steps", []) if not s["ok"]]
