"""Stability at the extremes: every integrator on scenes pushed to the edges of the range.

Each cell runs :func:`gyrotensegrity.simulate` (the user's path, fast dynamics) and reports
``holds`` with its constraint error and drift, ``fails`` with the library's error message
(stiffness detected, non-finite state with time and member, singular geometry), or
``budget`` when the wall-time budget ran out first (slow, not broken).
"""

import time
import tomllib

import numpy as np

from gyrohost.bench.runner import RunStopped, run_drifts
from gyrohost.parallel import Executor
from gyrohost.resources import shipped_dir
from gyrotensegrity import Model, SimulationError, scene_from_dict

SCENES = shipped_dir("scene")
SETTINGS = {
    "rk4": {"dt": 1e-3},
    "rk4-projected": {"dt": 1e-3},
    "dop853": {"rtol": 1e-9, "atol": 1e-12},
    "rk45": {"rtol": 1e-7, "atol": 1e-10},
    "radau": {"rtol": 1e-6, "atol": 1e-9},
    "bdf": {"rtol": 1e-6, "atol": 1e-9},
}


def scene_data(name: str) -> dict:
    with open(SCENES / f"{name}.toml", "rb") as fh:
        return tomllib.load(fh)


def with_spin(spin: float) -> dict:
    """The D-bar maneuver with every wheel at +-spin rad/s (the scene's pattern)."""
    data = scene_data("dbar-gyro")
    for bar in data["bars"]:
        bar["wheel"]["spin"] = float(np.sign(bar["wheel"]["spin"]) * spin)
    return data


def prism(stiffness=None, mass_ratio=None, scale=1.0, prestress=None) -> dict:
    """The free-floating gyroscopic prism, changed: string stiffness (N/m, rest lengths moved
    so that the initial tensions stay the scene's), wheel/bar mass ratio, all lengths scaled
    by ``scale`` (wheels too), or rest lengths at ``prestress`` times the initial lengths."""
    data = scene_data("prism-gyro")
    data["nodes"] = {k: [scale * c for c in v] for k, v in data["nodes"].items()}
    data["velocities"] = {k: [scale * c for c in v] for k, v in data["velocities"].items()}
    for bar in data["bars"]:
        w = bar["wheel"]
        w["radius"], w["thickness"] = scale * w["radius"], scale * w["thickness"]
        if mass_ratio is not None:
            w["mass"] = mass_ratio * bar["mass"]
    for s in data["strings"]:
        a, b = (np.array(data["nodes"][n]) for n in s["nodes"])
        length = float(np.linalg.norm(a - b))
        s["rest_length"] *= scale
        if prestress is not None:
            s["rest_length"] = prestress * length
        if stiffness is not None:
            stretch = (length - s["rest_length"]) * s["stiffness"] / stiffness
            s["rest_length"], s["stiffness"] = length - stretch, stiffness
    return data


def near_flat_dbar(height_ratio: float) -> dict:
    """The D-bar rhombus squashed so that n2, n4 sit at +-height_ratio of the bar length
    (the four bars almost collinear); the n1-n3 string then pulls it open by 10 % over 0.5 s,
    through the near-singular start."""
    data = with_spin(74.87462492)
    half = 0.3048  # bar length; n1, n3 at +-half*cos, n2, n4 at +-half*sin
    angle = np.arcsin(height_ratio)
    data["nodes"] = {
        "n1": [-half * np.cos(angle), 0.0, 0.0],
        "n2": [0.0, half * np.sin(angle), 0.0],
        "n3": [half * np.cos(angle), 0.0, 0.0],
        "n4": [0.0, -half * np.sin(angle), 0.0],
    }
    for s in data["strings"]:
        a, b = (np.array(data["nodes"][n]) for n in s["nodes"])
        length = float(np.linalg.norm(a - b))
        s["rest_length"] = length
        if s["name"] == "s13":
            s["rest_length"] = {"t": [0.0, 0.5], "value": [length, 0.9 * length]}
    return data


def zero_length_crossing() -> dict:
    """A free bar whose start node flies through a fixed anchor; the string between them
    (rest length 0) passes through zero length at t = 0.5 s."""
    return {
        "scene": {"name": "zero-length-crossing", "duration": 1.0},
        "nodes": {"o": [0.0, 0.0, 0.0], "a": [-0.5, 0.0, 0.0], "b": [-0.5, 0.0, 0.3]},
        "velocities": {"a": [1.0, 0.0, 0.0], "b": [1.0, 0.0, 0.0]},
        "constraints": {"fixed": ["o"]},
        "bars": [{"name": "bar", "nodes": ["a", "b"], "mass": 0.1}],
        "strings": [{"name": "s", "nodes": ["a", "o"], "stiffness": 1.0, "rest_length": 0.0}],
    }


def cells(quick: bool):
    """(group, label, scene dict, duration s) of the sweep."""
    short = 0.1 if quick else 0.5
    yield "wheel speed", "0 rad/s", with_spin(0.0), short
    yield "wheel speed", "3,000 rad/s", with_spin(3000.0), short
    yield "string stiffness", "1 N/m", prism(stiffness=1.0), short
    yield "string stiffness", "1e7 N/m", prism(stiffness=1e7), short
    yield "mass ratio wheel/bar", "1e-4", prism(mass_ratio=1e-4), short
    yield "mass ratio wheel/bar", "1e4", prism(mass_ratio=1e4), short
    yield "bar length", "1 mm", prism(scale=1e-3 / 0.3), short
    yield "bar length", "100 m", prism(scale=100.0 / 0.3), short
    yield "near-singular", "bars 1e-4 rad from collinear", near_flat_dbar(1e-4), short
    yield "near-singular", "strings 1e-6 from slack", prism(prestress=1.0 - 1e-6), short
    yield "near-singular", "string through zero length", zero_length_crossing(), 1.0
    yield (
        "long horizon",
        "prism 10 s" if quick else "prism 1,000 s",
        prism(),
        (10.0 if quick else 1000.0),
    )


def run_cell(data: dict, duration: float, integrator: str, budget_s: float) -> dict:
    """One cell: ``status`` holds / fails / budget, with figures or the error message."""
    from gyrotensegrity import simulate

    model = Model(scene_from_dict(data, source=data.get("scene", {}).get("name", "cell")))
    start = time.perf_counter()

    def progress(t, total):
        if time.perf_counter() - start > budget_s:
            raise RunStopped(f"{t:.3g} of {total:g} s in {budget_s:g} s")

    sample = min(0.01 * max(duration, 1.0), duration / 10)
    try:
        run = simulate(
            model,
            duration=duration,
            integrator=integrator,
            sample_dt=sample,
            constraint_tolerance=1e-3 * max(model.l.max(), 1e-3),
            progress=progress,
            fast=True,
            **SETTINGS[integrator],
        )
    except SimulationError as exc:
        return {"status": "fails", "message": str(exc), "wall_s": time.perf_counter() - start}
    except RunStopped as exc:
        return {"status": "budget", "message": str(exc), "wall_s": time.perf_counter() - start}
    bar = float(np.max(np.abs(run["bar_length_error"]) / model.l))
    joint = float(np.max(run["joint_error"], initial=0.0))
    finite = all(np.all(np.isfinite(run[k])) for k in ("N", "N_dot", "energy"))
    return {
        "status": "holds" if finite else "NaN",
        "bar_length_error": bar,
        "joint_error_m": joint,
        "momentum_drift": run_drifts(model, run)["momentum_drift"],
        "wall_s": time.perf_counter() - start,
    }


def sweep(quick: bool, log=print, executor=None) -> list:
    """Every cell with every integrator, each a case of ``executor``
    (:class:`gyrohost.parallel.Executor`; default serial in this process: the wall-time budgets
    assume a core of its own). Rows in cell order; ``log`` a line per cell as it finishes."""
    budget = 3.0 if quick else 60.0
    jobs = [
        (group, label, data, duration, integrator, budget)
        for group, label, data, duration in cells(quick)
        for integrator in SETTINGS
        if not (quick and integrator in ("rk45", "bdf"))
    ]
    if not quick:  # the long horizon is slow by design, not over budget
        jobs = [j if j[0] != "long horizon" else (*j[:5], 150.0) for j in jobs]

    def done(k, row):
        log(
            f"  {row['group']:22s} {row['cell']:30s} {row['integrator']:13s} {row['status']:6s} "
            + (
                row.get("message", "")[:70]
                if row["status"] != "holds"
                else f"bar {row['bar_length_error']:.1e}"
            )
        )

    return (executor or Executor(serial=True)).map(_job, jobs, on_done=done)


def _job(job) -> dict:
    """The row of one (group, label, scene data, duration, integrator, budget) job."""
    group, label, data, duration, integrator, budget_s = job
    cell = run_cell(data, duration, integrator, budget_s)
    return {"group": group, "cell": label, "integrator": integrator, "duration_s": duration, **cell}
