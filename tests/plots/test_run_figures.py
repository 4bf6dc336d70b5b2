"""``gyrotens plot`` of run files too large to draw whole: thinned or refused, and said which,
before memory or time run away (a 10,000-bar run file once took 3.9 GB and more than 120 s)."""

import json

import numpy as np
import pytest

from gyrohost.cli import main
from gyrohost.plots import model
from gyrotensegrity.runfile import Run


def run_file(path, bars: int, samples: int):
    """A run file of ``bars`` bars (two nodes each, no strings) and ``samples`` samples: the
    arrays the figures read, values that draw."""
    nodes = 2 * bars
    t = np.linspace(0.0, 1.0, samples)
    c_b = np.zeros((bars, nodes), dtype=np.int8)
    c_b[np.arange(bars), 2 * np.arange(bars)] = -1
    c_b[np.arange(bars), 2 * np.arange(bars) + 1] = 1
    arrays = {
        "t": t,
        "N": np.sin(t)[:, None, None] * np.ones((1, 3, nodes)),
        "node_names": np.array([f"n{i}" for i in range(nodes)]),
        "bar_length_error": 1e-9 * np.ones((samples, bars)),
        "joint_error": np.zeros((samples, 0)),
        "energy": 1.0 + 1e-12 * t,
        "angular_momentum": np.ones((samples, 3)),
        "scene": np.array(json.dumps({"name": "big"})),
        "C_b": c_b,
        "C_s": np.zeros((0, nodes), dtype=np.int8),
    }
    return Run(arrays).save(path)


def test_a_scene_of_many_bars_is_drawn_thinned_and_not_animated(tmp_path, capsys):
    path = run_file(tmp_path / "big.npz", bars=2000, samples=20)
    assert main(["plot", str(path), "-o", str(tmp_path / "fig")]) == 0
    out, err = capsys.readouterr()
    assert sorted(p.name for p in (tmp_path / "fig").iterdir()) == [
        "big-constraints.png", "big-invariants.png", "big-nodes.png"]  # fmt: skip
    traces = model.max_traces()
    assert err.splitlines() == [
        f"gyrotens plot: warning: animation left out: 2000 bars and strings, more than "
        f"{model.MAX_ANIMATED}",
        f"gyrotens plot: warning: big-nodes.png: 4000 nodes, 1 in {-(-4000 // traces)} drawn",
        "gyrotens plot: warning: big-constraints.png: 2000 bars, drawn as their largest error",
    ]


def test_a_long_run_is_drawn_at_every_kth_sample(tmp_path, capsys):
    path = run_file(tmp_path / "long.npz", bars=2, samples=3 * model.MAX_POINTS + 1)
    assert main(["plot", str(path), "-o", str(tmp_path / "fig"), "--no-animation"]) == 0
    assert capsys.readouterr().err == (
        f"gyrotens plot: warning: {3 * model.MAX_POINTS + 1} samples, 1 in 4 drawn\n"
    )


def test_a_run_file_too_large_to_read_is_refused_before_it_is_read(tmp_path, capsys, monkeypatch):
    path = run_file(tmp_path / "big.npz", bars=200, samples=100)
    n_bytes = 8 * 100 * 3 * 400  # its N alone
    monkeypatch.setattr(model, "MAX_READ_BYTES", n_bytes)
    read = []
    monkeypatch.setattr(model.RunFile, "__getitem__", lambda self, name: read.append(name))
    assert main(["plot", str(path), "-o", str(tmp_path / "fig"), "--no-animation"]) == 2
    err = capsys.readouterr().err
    assert f"{path}: its figures would read " in err and "plot a shorter run" in err, err
    assert read == [] and not (tmp_path / "fig").exists()


@pytest.mark.parametrize("content", [b"PK\x03\x04 not a zip", b""])
def test_a_damaged_run_file_is_one_line(tmp_path, capsys, content):
    path = tmp_path / "bad.npz"
    path.write_bytes(content)
    assert main(["plot", str(path), "-o", str(tmp_path / "fig")]) == 2
    assert "gyrotens plot: error: " in capsys.readouterr().err
