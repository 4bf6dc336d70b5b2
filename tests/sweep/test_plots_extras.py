"""The Pareto front and the figures of a sweep; the sweep extra reaches make test's install."""

import importlib.util
from pathlib import Path

import numpy as np

from gyrohost.sweep.plots import heatmap, pareto, pareto_front
from gyrohost.sweep.spec import load_spec

ROOT = Path(__file__).resolve().parents[2]


def test_pareto_front_keeps_only_the_non_dominated_points():
    cost = np.array([1.0, 2.0, 2.0, 3.0, 4.0, np.nan, 0.5])
    score = np.array([5.0, 3.0, 4.0, 3.5, 1.0, 0.0, np.inf])
    assert pareto_front(cost, score).tolist() == [0, 1, 4]


def test_heatmap_and_pareto_of_the_dbar_turn_spec_write_pngs(tmp_path):
    spec = load_spec("dbar-turn")
    spins, closures = (a.values for a in spec.axes)
    rows = [
        {"spin_rad_s": s, "closure_s": c, "final_tilt_deg": -s / c} for s in spins for c in closures
    ]
    for draw, name in ((heatmap, "heatmap.png"), (pareto, "pareto.png")):
        path = draw(spec, rows, tmp_path / name)
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_extras_expand_the_projects_own_extras():
    spec = importlib.util.spec_from_file_location("extras", ROOT / "tools" / "extras.py")
    extras = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(extras)
    project = {
        "name": "gyrotensegrity",
        "optional-dependencies": {
            "test": ["pytest>=9.2", "gyrotensegrity[sweep]"],
            "sweep": ["dask[distributed]>=2026.8", "pyarrow>=26.0"],
            "dev": ["gyrotensegrity[test, sweep]"],
        },
    }
    want = ["pytest>=9.2", "dask[distributed]>=2026.8", "pyarrow>=26.0"]
    assert extras.requirements(project, ["test"]) == want
    assert extras.requirements(project, ["dev"]) == want
    real = extras.requirements(
        extras.tomllib.loads(extras.PYPROJECT.read_text())["project"], ["test"]
    )
    assert any(r.startswith("dask[distributed]") for r in real)
