"""Double pendulum (class-2 joint + fixed node) against a minimal-coordinate ODE."""

from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

import gyrotensegrity
from gyrotensegrity import Model, load_scene, simulate

SCENES = Path(gyrotensegrity.__file__).parent / "scenes"
L1, L2, M1, M2, G = 0.5, 0.4, 1.0, 0.8, 9.81


def pendulum_rhs(t, y):
    """Two uniform rods in the x-z plane; angles from the downward vertical (Lagrange)."""
    th1, th2, w1, w2 = y
    c, s = np.cos(th1 - th2), np.sin(th1 - th2)
    M = np.array([[M1 * L1**2 / 3 + M2 * L1**2, 0.5 * M2 * L1 * L2 * c],
                  [0.5 * M2 * L1 * L2 * c, M2 * L2**2 / 3]])  # fmt: skip
    f = np.array([
        -0.5 * M2 * L1 * L2 * s * w2**2 - (0.5 * M1 + M2) * G * L1 * np.sin(th1),
        0.5 * M2 * L1 * L2 * s * w1**2 - 0.5 * M2 * G * L2 * np.sin(th2),
    ])  # fmt: skip
    return np.concatenate([[w1, w2], np.linalg.solve(M, f)])


def test_double_pendulum_matches_minimal_coordinates():
    model = Model(load_scene(SCENES / "double-pendulum.toml"))
    assert "multipliers" in model.terms and "gyroscopic" not in model.terms
    run = simulate(model, duration=5.0, rtol=1e-12, atol=1e-14)
    t = run["t"]
    ref = solve_ivp(pendulum_rhs, (0, 5), [0.6, -0.3, 0, 0], method="DOP853",
                    rtol=1e-13, atol=1e-14, t_eval=t)  # fmt: skip
    th1, th2 = ref.y[0], ref.y[1]
    n1 = np.stack([L1 * np.sin(th1), 0 * th1, -L1 * np.cos(th1)])
    n2 = n1 + np.stack([L2 * np.sin(th2), 0 * th2, -L2 * np.cos(th2)])
    names = list(run["node_names"])
    N = run["N"]
    err1 = np.abs(N[:, :, names.index("n1")] - n1.T).max()
    err2 = np.abs(N[:, :, names.index("n2")] - n2.T).max()
    assert max(err1, err2) <= 1e-9, (err1, err2)
    assert np.abs(run["joint_error"]).max() <= 1e-12
