"""gyrotens simulate and plot on a short run; user errors exit with status 2."""

import numpy as np

from gyrohost.cli import main


def test_simulate_then_plot(tmp_path):
    out = tmp_path / "run.npz"
    scene = "double-pendulum"  # a shipped scene, by name
    args = ["simulate", scene, "-o", str(out), "--duration", "0.2", "--integrator", "rk4"]
    assert main(args) == 0
    with np.load(out) as z:
        assert z["N"].shape == (21, 3, 4) and list(z["node_names"]) == ["n0", "n1", "n1", "n2"]
        assert z["C_b"].shape == (2, 4) and z["rest_length"].shape == (21, 0)
    assert main(["plot", str(out), "-o", str(tmp_path / "fig"), "--no-animation"]) == 0
    assert (tmp_path / "fig" / "double-pendulum-nodes.png").stat().st_size > 1000


def test_bad_scene_is_a_user_error(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('[scene]\n[nodes]\na = [0, 0, 0]\n[[bars]]\nnodes = ["a", "x"]\nmass = 1\n')
    assert main(["simulate", str(bad), "-o", str(tmp_path / "r.npz")]) == 2
    assert "bad.toml: bars[0].nodes[1]: unknown node 'x'" in capsys.readouterr().err
