"""One run of a schedule on the rig, from connection to the safe state, logged.

Modules, in the order a run meets them: :mod:`.request` (a run as a user asks for it, checked
before anything opens: what ``gyrotens run`` calls), :mod:`.sequence` (the phases,
:class:`RunLoop`), :mod:`.limits` (the schedule checked before anything moves, limits every tick),
:mod:`.devices` (reader threads), :mod:`.ticker` (the clock and fixed tick grid),
:mod:`.dispatch` (per-device handling of samples), :mod:`.streams` (the log schema),
:mod:`.log` (the log format), :mod:`.safe_state`, :mod:`.summary`, :mod:`.simulated` (a run on
the simulated rig), :mod:`.replay` (the estimator over a log), :mod:`.errors`.
"""

import importlib

_PUBLIC = {
    "LimitBreach": "errors",
    "LoopTimer": "ticker",
    "RunError": "errors",
    "RunLoop": "sequence",
    "RunResult": "settings",
    "RunSettings": "settings",
    "ScheduleRefused": "errors",
    "check_schedule": "limits",
    "jitter_line": "ticker",
    "run_simulated": "simulated",
    "with_ports": "connect",
}
"""Public name -> its module; imported on first use, so ``gyrohost.run.log`` (read by the plots)
does not import the drivers, the estimator and the model."""

__all__ = sorted(_PUBLIC)


def __getattr__(name: str):
    if name not in _PUBLIC:
        raise AttributeError(f"module 'gyrohost.run' has no attribute '{name}'")
    return getattr(importlib.import_module(f"gyrohost.run.{_PUBLIC[name]}"), name)
