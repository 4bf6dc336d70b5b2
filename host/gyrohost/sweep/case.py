"""One case of a sweep: the scene with the case's values, simulated, and its recorded quantities.

A :class:`Task` is plain data (picklable) and :func:`run_case` a module-level function, so a case
runs the same in this process and on a Dask worker: the model is built inside the task.
"""

import hashlib
import json
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from gyrohost.bench.runner import run_drifts
from gyrohost.control.attitude import TiltMeter
from gyrotensegrity import Model, __version__, scene_from_dict, simulate

from .spec import Spec, apply


@dataclass(frozen=True)
class Task:
    """One case to run.

    Attributes
    ----------
    index : int
        Position in the sweep's case list.
    case_id : str
        Hash of everything the result depends on (scene data, integrator, records, the
        package's version): a finished case with the same id is not run again.
    values : tuple of float
        The axis values, in axis order.
    scene : dict
        The scene data with the values written in.
    integrator : dict
        Keyword arguments of :func:`gyrotensegrity.simulate`.
    record : tuple of str
    source : str
        Name of the case in error messages (``dbar-turn case 12``).
    """

    index: int
    case_id: str
    values: tuple
    scene: dict
    integrator: dict
    record: tuple
    source: str


def tasks(spec: Spec, values: Iterable[tuple]) -> Iterator[Task]:
    """The :class:`Task` of every case, one at a time (``values``: one tuple of axis values
    per case)."""
    for k, case in enumerate(values):
        scene = apply(spec.scene, spec.axes, case)
        key = json.dumps([scene, spec.integrator, spec.record, __version__], sort_keys=True)
        case_id = hashlib.sha256(key.encode()).hexdigest()[:16]
        yield Task(k, case_id, case, scene, spec.integrator, tuple(spec.record),
                   f"{spec.name} case {k}")  # fmt: skip


def run_case(task: Task) -> dict:
    """Simulate one case (fast dynamics) and return its recorded quantities.

    Returns
    -------
    dict
        Recorded name -> float (a run-file quantity with more than one number per sample: a list
        of floats, flattened; an energy drift of a scene that does work: None).

    Raises
    ------
    gyrotensegrity.SceneError, gyrotensegrity.SimulationError
        The case's scene is invalid or its run stopped (the sweep records the message).
    """
    model = Model(scene_from_dict(task.scene, source=task.source))
    start = time.perf_counter()
    run = simulate(model, fast=True, **task.integrator)
    wall_s = time.perf_counter() - start
    drifts = None
    out = {}
    for name in task.record:
        if name == "wall_s":
            out[name] = wall_s
        elif name == "final_tilt_deg":
            out[name] = final_tilt_deg(model, run)
        elif name == "peak_node_z_m":
            out[name] = float(np.max(run["N"][:, 2, :]))
        elif name in ("energy_drift", "momentum_drift"):
            drifts = drifts or run_drifts(model, run)
            out[name] = drifts[name]
        else:
            out[name] = run_quantity(run, name)
    return out


def final_tilt_deg(model, run) -> float:
    """The D-bar's turn at the end of the run, degrees: the tilt
    (:class:`gyrohost.control.attitude.TiltMeter`) unwrapped over the samples, so a turn past
    180 degrees counts whole instead of wrapping to the other sign."""
    meter = TiltMeter(model)
    tilt = np.unwrap([meter.tilt(N) for N in run["N"]])
    return float(np.degrees(tilt[-1]))


def run_quantity(run, name: str):
    """``quantity[:reducer]`` of a run file, reduced over time (``final`` by default).

    Raises
    ------
    KeyError
        No such quantity in the run file (the message lists them).
    """
    quantity, _, reducer = name.partition(":")
    if quantity not in run.arrays:
        raise KeyError(
            f"{name}: no quantity {quantity!r} in the run file ({', '.join(run.arrays)})"
        )
    a = np.asarray(run[quantity], dtype=float)
    if a.ndim == 0 or len(a) != len(run["t"]):
        value = a  # a constant of the run (masses, stiffnesses)
    else:
        value = {
            "final": lambda: a[-1],
            "max": lambda: a.max(axis=0),
            "min": lambda: a.min(axis=0),
            "mean": lambda: a.mean(axis=0),
            "maxabs": lambda: np.abs(a).max(axis=0),
        }[reducer or "final"]()
    value = np.ravel(value)
    return float(value[0]) if value.size == 1 else [float(v) for v in value]
