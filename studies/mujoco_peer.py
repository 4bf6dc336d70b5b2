"""Whole-process comparison with MuJoCo: ``gyrotens simulate`` against a MuJoCo script.

Two modes::

    python -m studies.mujoco_peer SCENE -o OUT.npz [--duration 1] [--dt 1e-4]
    python -m studies.mujoco_peer --compare [--scene dbar-gyro] [--duration 1]

The first is the MuJoCo script: it imports MuJoCo, builds the scene as MuJoCo bodies
(:func:`gyrohost.bench.peers.run_mujoco`, RK4), runs it and writes the primary nodes' positions
(``t``, ``N``). The second times, as separate processes (interpreter start and imports
included), ``gyrotens simulate SCENE --duration D`` and that script on the same scene, best of
``--repeats``, and scores both against one reference trajectory (our DOP853 at rtol 1e-13):
the table in docs/performance.md.
"""

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from gyrohost.resources import resolve

DT_S, SOLREF_S, SOLIMP = 1e-4, 2e-4, 0.9999
"""MuJoCo's step and its stiffest loop closure that stays stable at that step (bench peers)."""
SAMPLE_DT_S = 0.01


def mujoco_script(scene: Path, out: Path, duration_s: float, dt_s: float) -> None:
    """The MuJoCo run of ``scene``: primary node positions every 10 ms into ``out`` (.npz)."""
    from gyrohost.bench.peers import run_mujoco
    from gyrotensegrity import Model, load_scene

    model = Model(load_scene(scene))
    r = run_mujoco(model, dt_s, SOLREF_S, duration_s, SAMPLE_DT_S, SOLIMP)
    np.savez(out, t=r["t"], N=r["N"], gap_m=r["gap_m"])


def timed(cmd: list[str], repeats: int) -> float:
    """Smallest wall time of ``repeats`` runs of ``cmd`` as a new process, s."""
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True)
        best = min(best, time.perf_counter() - start)
    return best


def compare(scene: Path, duration_s: float, repeats: int) -> dict:
    """Wall times (whole process) and max node errors of ours and MuJoCo against a reference."""
    from gyrohost.bench.runner import Variant, integrate
    from gyrohost.bench.trade import REFERENCE
    from gyrotensegrity import Model, load_run, load_scene
    from gyrotensegrity.fast import FastDynamics

    model = Model(load_scene(scene))
    ref = integrate(Variant(scene.stem, model), *REFERENCE, duration_s, SAMPLE_DT_S)
    primary = [model.structure.primary[n] for n in model.scene.node_names]
    gyrotens = Path(sys.executable).with_name("gyrotens")
    with tempfile.TemporaryDirectory() as tmp:
        ours_out, peer_out = Path(tmp) / "ours.npz", Path(tmp) / "mujoco.npz"
        ours_cmd = [str(gyrotens), "simulate", str(scene), "--duration", f"{duration_s:g}"]
        ours_cmd += ["-o", str(ours_out)]
        peer_cmd = [sys.executable, "-m", __spec__.name, str(scene), "-o", str(peer_out)]
        peer_cmd += ["--duration", f"{duration_s:g}", "--dt", f"{DT_S:g}"]
        result = {
            "scene": scene.stem,
            "duration_s": duration_s,
            "kernel": FastDynamics(model).kernel is not None,
            "ours_wall_s": timed(ours_cmd, repeats),
            "mujoco_wall_s": timed(peer_cmd, repeats),
            "bare_python_s": timed([sys.executable, "-c", "pass"], repeats),
        }
        ours = load_run(ours_out)
        with np.load(peer_out) as peer:
            peer_n, result["mujoco_gap_m"] = peer["N"], float(peer["gap_m"])
        result["ours_meta"] = {k: ours.meta[k] for k in ("integrator", "rtol", "fast")}
        ours_n = ours["N"][:, :, primary]
    reference = ref.N[:, :, primary]
    result["ours_error_m"] = float(np.max(np.abs(ours_n - reference[: len(ours_n)])))
    result["mujoco_error_m"] = float(np.max(np.abs(peer_n - reference[: len(peer_n)])))
    return result


def markdown(r: dict) -> str:
    """The docs/performance.md table of one :func:`compare` result."""
    m = r["ours_meta"]
    return "\n".join(
        [
            f"| process ({r['scene']}, {r['duration_s']:g} s simulated) | wall (s) "
            "| max node error (m) |",
            "|---|---|---|",
            f"| `gyrotens simulate` ({m['integrator']}, rtol {m['rtol']:g}, "
            f"{'fast' if m['fast'] else 'reference'} path, kernel "
            f"{'yes' if r['kernel'] else 'no'}) | {r['ours_wall_s']:.3f} | "
            f"{r['ours_error_m']:.1e} |",
            f"| MuJoCo script (RK4, dt {DT_S:g} s, solref {SOLREF_S:g}, solimp {SOLIMP}) | "
            f"{r['mujoco_wall_s']:.3f} | {r['mujoco_error_m']:.1e} |",
            f"| bare `python -c pass` | {r['bare_python_s']:.3f} | |",
        ]
    )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m studies.mujoco_peer", description=__doc__)
    p.add_argument("scene", nargs="?", default="dbar-gyro", help="scene file or shipped name")
    p.add_argument("-o", "--out", type=Path, help="MuJoCo run: node positions (.npz)")
    p.add_argument("--duration", type=float, default=1.0, help="simulated time, s")
    p.add_argument("--dt", type=float, default=DT_S, help="MuJoCo RK4 step, s")
    p.add_argument("--compare", action="store_true", help="time and score both processes")
    p.add_argument("--repeats", type=int, default=5, help="runs per process (best counts)")
    a = p.parse_args(argv)
    scene = resolve("scene", a.scene)
    if a.compare:
        print(markdown(compare(scene, a.duration, a.repeats)))
        return 0
    if a.out is None:
        p.error("give -o OUT.npz (or --compare)")
    mujoco_script(scene, a.out, a.duration, a.dt)
    return 0


if __name__ == "__main__":
    sys.exit(main())
