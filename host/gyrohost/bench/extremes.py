"""Stability at the extremes: every integrator on scenes pushed to the edges of the range.

Each cell runs :func:`gyrotensegrity.simulate` (the user's path, fast dynamics) and compares
its node positions with a tight reference of the same scene (DOP853 at two tolerances,
:data:`REFERENCE`). A cell ``holds`` only when it agrees with the reference within its
integrator's accuracy class (:data:`ACCURACY_CLASS`, relative to the structure's extent). It
is ``sensitive`` when the two reference runs themselves differ by more than that class (the
motion amplifies round-off, e.g. a fold instability: no integrator settles it),
``inaccurate`` when the references agree and the cell does not (its setting is too loose
there), ``unverified`` when the references did not finish. ``fails`` carries the library's
error message (stiffness detected, non-finite state with time and member, singular geometry),
``budget`` says the wall-time budget ran out first (slow, not broken).
"""

import time

import numpy as np

from gyrohost.bench.errors import RunStopped
from gyrohost.bench.runner import run_drifts
from gyrohost.parallel import Executor
from gyrohost.resources import shipped_dir
from gyrotensegrity import Model, SimulationError, scene_from_dict
from gyrotensegrity.compat import tomllib

SCENES = shipped_dir("scene")
SETTINGS = {
    "rk4": {"dt": 1e-3},
    "rk4-projected": {"dt": 1e-3},
    "dop853": {"rtol": 1e-9, "atol": 1e-12},
    "rk45": {"rtol": 1e-7, "atol": 1e-10},
    "radau": {"rtol": 1e-6, "atol": 1e-9},
    "bdf": {"rtol": 1e-6, "atol": 1e-9},
}
ACCURACY_CLASS = {
    "rk4": 1e-3,
    "rk4-projected": 1e-3,
    "dop853": 1e-6,
    "rk45": 1e-3,
    "radau": 1e-3,
    "bdf": 1e-3,
}
"""Largest node difference from the reference, relative to the structure's extent, for which
a cell of the integrator (at its :data:`SETTINGS`) holds."""
REFERENCE = ("dop853", (1e-11, 1e-13))  # integrator, the two rtol (atol rtol / 1000 x extent)


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
    data.pop("attitude", None)  # folded flat, n2 and n4 meet: the D-bar's frame has no y axis
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
    yield "wheel speed", "10,000 rad/s", with_spin(1e4), 1.0
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


def _simulate(model, duration: float, integrator: str, settings: dict, budget_s: float):
    """A fast-path run sampled as every run of the cell, stopped at the wall-time budget."""
    from gyrotensegrity import simulate

    start = time.perf_counter()

    def progress(t, total):
        if time.perf_counter() - start > budget_s:
            raise RunStopped(f"{t:.3g} of {total:g} s in {budget_s:g} s")

    return simulate(
        model,
        duration=duration,
        sample_dt=min(0.01 * max(duration, 1.0), duration / 10),
        integrator=integrator,
        constraint_tolerance=1e-3 * max(model.l.max(), 1e-3),
        progress=progress,
        fast=True,
        **settings,
    )


def extent(model) -> float:
    """The structure's size at the start, m: the largest spread of its node coordinates."""
    return float(np.max(np.ptp(model.structure.N0, axis=1)))


def reference(data: dict, duration: float, budget_s: float) -> dict | None:
    """The cell's reference: DOP853 at the two :data:`REFERENCE` tolerances.

    Returns
    -------
    dict
        ``N`` (K, 3, n) m of the tighter run; ``spread``: the largest node difference between
        the two, relative to the extent; ``spread_t_s``: when it is largest. Only ``message``
        when a reference run failed or ran out of budget.
    """
    model = model_of(data)
    size = extent(model)
    integrator, tolerances = REFERENCE
    runs = []
    for r in tolerances:
        try:
            settings = {"rtol": r, "atol": 1e-3 * r * size}
            runs.append(_simulate(model, duration, integrator, settings, budget_s))
        except (SimulationError, RunStopped) as exc:
            return {"message": f"reference {integrator} at rtol {r:g} did not finish: {exc}"}
    diff = np.max(np.abs(runs[0]["N"] - runs[1]["N"]), axis=(1, 2)) / size
    k = int(np.argmax(diff))
    return {"N": runs[1]["N"], "spread": float(diff[k]), "spread_t_s": float(runs[1]["t"][k])}


def model_of(data: dict) -> Model:
    return Model(scene_from_dict(data, source=data.get("scene", {}).get("name", "cell")))


def run_cell(data: dict, duration: float, integrator: str, budget_s: float, ref=None) -> dict:
    """One cell: ``status`` (see the module docstring) with figures or the error message.

    Parameters
    ----------
    ref : dict or None
        The cell's :func:`reference`; without its nodes (None, or a reference that did not
        finish) the status of a finished run is ``unverified``.
    """
    model = model_of(data)
    start = time.perf_counter()
    try:
        run = _simulate(model, duration, integrator, SETTINGS[integrator], budget_s)
    except SimulationError as exc:
        return {"status": "fails", "message": str(exc), "wall_s": time.perf_counter() - start}
    except RunStopped as exc:
        return {"status": "budget", "message": str(exc), "wall_s": time.perf_counter() - start}
    wall = time.perf_counter() - start
    bar = float(np.max(np.abs(run["bar_length_error"]) / model.l))
    joint = float(np.max(run["joint_error"], initial=0.0))
    figures = {
        "bar_length_error": bar,
        "joint_error_m": joint,
        "momentum_drift": run_drifts(model, run)["momentum_drift"],
        "wall_s": wall,
    }
    if not all(np.all(np.isfinite(run[k])) for k in ("N", "N_dot", "energy")):
        return {"status": "NaN", **figures}
    return {**figures, **_agreement(model, run["N"], integrator, ref)}


def _agreement(model, N, integrator: str, ref) -> dict:
    """Status and message of a finished run from its node difference to the reference."""
    if ref is None or "N" not in ref:
        return {"status": "unverified", "message": ref["message"] if ref else "no reference"}
    size, bound = extent(model), ACCURACY_CLASS[integrator]
    error = float(np.max(np.abs(N - ref["N"]))) / size
    out = {"node_error": error, "reference_spread": ref["spread"]}
    if error <= bound:
        return {**out, "status": "holds"}
    rtols = " and ".join(f"{r:g}" for r in REFERENCE[1])
    if ref["spread"] > bound:
        why = (
            f"{REFERENCE[0]} runs at rtol {rtols} differ by {ref['spread'] * size:.2g} m "
            f"(at {ref['spread_t_s']:.3g} s): the motion amplifies round-off"
        )
        return {**out, "status": "sensitive", "message": why}
    why = f"node error {error * size:.2g} m against the reference, class {bound:g} x extent"
    return {**out, "status": "inaccurate", "message": why}


def sweep(quick: bool, log=print, executor=None) -> list:
    """Every cell with every integrator, each a case of ``executor``
    (:class:`gyrohost.parallel.Executor`; default serial in this process: the wall-time budgets
    assume a core of its own). Rows in cell order; ``log`` a line per cell as it finishes."""
    budget = 3.0 if quick else 60.0
    executor = executor or Executor(serial=True)
    cell_list = list(cells(quick))

    def long(group: str) -> bool:  # the long horizon is slow by design, not over budget
        return group == "long horizon" and not quick

    refs = executor.map(
        _reference_job,
        [(data, duration, 300.0 if long(g) else 4 * budget) for g, _, data, duration in cell_list],
    )
    jobs = [
        (group, label, data, duration, integrator, 150.0 if long(group) else budget, ref)
        for (group, label, data, duration), ref in zip(cell_list, refs, strict=True)
        for integrator in SETTINGS
        if not (quick and integrator in ("rk45", "bdf"))
    ]

    def done(k, row):
        log(
            f"  {row['group']:22s} {row['cell']:30s} {row['integrator']:13s} {row['status']:10s} "
            + (
                row.get("message", "")[:70]
                if row["status"] != "holds"
                else f"node {row['node_error']:.1e} bar {row['bar_length_error']:.1e}"
            )
        )

    return executor.map(_job, jobs, on_done=done)


def _reference_job(job) -> dict | None:
    """:func:`reference` of one (scene data, duration, budget) cell."""
    return reference(*job)


def _job(job) -> dict:
    """The row of one (group, label, scene data, duration, integrator, budget, reference) job."""
    group, label, data, duration, integrator, budget_s, ref = job
    cell = run_cell(data, duration, integrator, budget_s, ref)
    return {"group": group, "cell": label, "integrator": integrator, "duration_s": duration, **cell}
