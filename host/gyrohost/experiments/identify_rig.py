"""Identification on the real-time simulated rig, end to end, through the commands a lab uses.

``python -m gyrohost.experiments.identify_rig [--seeds 1] [--out DIR] [--lengths servos]
[--until S] [--segment-s S] [--fit-only]``

Per seed (the simulated IMU's noise and biases):

1. ``gyrotens run --sim --config C --truth-scene T --schedule identify -o LOG``: the truth ``T``
   is the shipped D-bar with J3 x 1.3, bar mass x 0.8, string stiffness x 1.25 and damping
   x 0.7; ``C`` is ``sim-rig`` with the bars weighed (its scene: the shipped D-bar with the
   truth's bar mass) and the truth's IMU turned (3, -1.7, 1.1) degrees from where ``C`` says
   it is (``[sim.truth] imu_rotation_deg``);
2. ``gyrotens identify LOG -o IDENT.toml --config C --overlay OVERLAY.toml --segment-s 4``
   (the whole log, in multiple-shooting segments; ``--until S`` fits only its first ``S``
   seconds);
3. ``gyrotens run --sim --config C --overlay RUN.toml --scene IDENT.toml --truth-scene T``,
   ``RUN.toml`` the fit's ``OVERLAY.toml`` with the truth's IMU kept where it was
   (:func:`truth_kept_overlay`: ``[sim.truth] imu_rotation_deg`` turns the emulated IMU from
   where the configuration says it is, and the overlay moves that to the identified mounting).

It prints each identified figure's error against the truth (J3, stiffness and damping as
relative errors, the mounting in degrees), the fit's wall time and the exit status of every
command. The rig runs are real time: run this at normal priority on a quiet machine.
"""

import argparse
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

from gyrohost.experiments.identify_check import FACTORS, IMU_ROTATION_DEG, wheel_speed_error
from gyrohost.resources import shipped

J3_NOMINAL = 0.5 * 0.050 * 0.031**2  # the shipped D-bar's wheel disc, kg m^2


def write_rig_files(folder: Path, seed: int = 1) -> tuple[Path, Path]:
    """The host's configuration ``C`` (bars weighed) and the truth scene ``T`` in ``folder``.

    Returns
    -------
    config, truth : Path
    """
    text = Path(shipped("scene", "dbar-gyro")).read_text()
    mass = f"mass = {0.1 * FACTORS['bar_mass']!r}"
    weighed = text.replace("mass = 0.10", mass)
    (folder / "weighed.toml").write_text(weighed.replace('name = "dbar-gyro"', 'name = "weighed"'))
    f = FACTORS
    truth = weighed.replace('name = "dbar-gyro"', 'name = "truth"')
    truth = truth.replace("stiffness = 200.0", f"stiffness = {200.0 * f['stiffness']!r}")
    truth = truth.replace("damping = 2.0", f"damping = {2.0 * f['damping']!r}")
    truth = truth.replace("spin = ", f"J3 = {J3_NOMINAL * f['J3']!r}, spin = ")
    (folder / "truth.toml").write_text(truth)
    config = wheel_speed_error(Path(shipped("config", "sim-rig")).read_text(), 0.0)
    config = config.replace('scene = "dbar-gyro"', 'scene = "weighed.toml"')
    config = config.replace("seed = 1\n", f"seed = {seed}\n", 1)
    rotation = ", ".join(repr(a) for a in IMU_ROTATION_DEG)
    config += f"\n[sim.truth]\nimu_rotation_deg = [{rotation}]\n"
    (folder / "rig.toml").write_text(config)
    return folder / "rig.toml", folder / "truth.toml"


def gyrotens(args: list[str], nice: bool = False) -> int:
    """Run ``gyrotens ARGS`` in a child process (niced if asked); its exit status."""
    cmd = [sys.executable, "-m", "gyrohost", *args]
    return subprocess.run(["nice", "-n", "19", *cmd] if nice else cmd, check=False).returncode


def identified_errors(ident: Path, overlay: Path) -> dict[str, float]:
    """Relative errors of J3, stiffness and damping and the mounting's error (degrees, each
    axis) of an identified scene and overlay against the truth."""
    scene = tomllib.loads(ident.read_text())
    wheel = scene["bars"][0]["wheel"]
    string = scene["strings"][0]
    out = {
        "J3": wheel["J3"] / (J3_NOMINAL * FACTORS["J3"]) - 1.0,
        "stiffness": string["stiffness"] / (200.0 * FACTORS["stiffness"]) - 1.0,
        "damping": string["damping"] / (2.0 * FACTORS["damping"]) - 1.0,
    }
    rpy = np.degrees(tomllib.loads(overlay.read_text())["imu"]["mounting_rpy_rad"])
    for axis, got, true in zip(("roll", "pitch", "yaw"), rpy, IMU_ROTATION_DEG, strict=True):
        out[f"mounting.{axis}_deg"] = float(got - true)
    return out


def truth_kept_overlay(overlay: Path, out: Path) -> Path:
    """``overlay`` (what ``gyrotens identify`` wrote) with ``[sim.truth] imu_rotation_deg`` set
    so that the emulated IMU stays at the truth's mounting (:data:`IMU_ROTATION_DEG` from a zero
    mounting) now that the host's is the identified one, written to ``out``.

    The emulator turns the IMU by ``imu_rotation_deg`` from the configuration's mounting:
    without this the overlay would turn the truth's IMU by the identified mounting as well, and
    the run would test a rig the fit never saw."""
    from gyrohost.geometry import euler_zyx, rotation_zyx

    text = overlay.read_text()
    identified = tomllib.loads(text)["imu"]["mounting_rpy_rad"]
    turn = rotation_zyx(*np.radians(IMU_ROTATION_DEG)) @ rotation_zyx(*identified).T
    deg = ", ".join(repr(float(a)) for a in np.degrees(euler_zyx(turn)))
    out.write_text(text + f"\n[sim.truth]\nimu_rotation_deg = [{deg}]\n")
    return out


def truth_lag_s(log: Path) -> float:
    """Median lag (s) of the simulated rig's truth behind real time in the run: a loaded CPU
    makes the recording's physics lag its time stamps."""
    from gyrohost.run.log import read_stream

    truth = read_stream(log, "truth")
    return float(np.median(truth["rig_t_s"] - truth["truth_t_s"]))


def one_seed(root: Path, seed: int, args) -> dict:
    """The three commands for one seed in ``root/seedN`` (``args``: the options of
    :func:`main`; with ``fit_only`` the recording is the one already there and the third
    command is not run); what they gave."""
    folder = root / f"seed{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    log, ident, overlay = folder / "ident-run", folder / "ident.toml", folder / "overlay.toml"
    config, truth = folder / "rig.toml", folder / "truth.toml"
    out = {}
    if not args.fit_only:
        config, truth = write_rig_files(folder, seed)
        rig = ["--sim", "--config", str(config), "--truth-scene", str(truth)]
        out["record"] = gyrotens(["run", *rig, "--schedule", "identify", "-o", str(log)])
    out["truth_lag_s"] = truth_lag_s(log)
    window = [] if args.until is None else ["--until", str(args.until)]
    t0 = time.perf_counter()
    out["identify"] = gyrotens(
        ["identify", str(log), "-o", str(ident), "--config", str(config),
         "--overlay", str(overlay), "--lengths", args.lengths,
         "--segment-s", str(args.segment_s), *window], nice=True,
    )  # fmt: skip
    out["fit_s"] = time.perf_counter() - t0
    if out["identify"] == 0 and not args.fit_only:
        kept = truth_kept_overlay(overlay, folder / "run-overlay.toml")
        out["replay"] = gyrotens(
            ["run", *rig, "--overlay", str(kept), "--scene", str(ident),
             "-o", str(folder / "with-ident")]
        )  # fmt: skip
    if out["identify"] == 0:
        out["errors"] = identified_errors(ident, overlay)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gyrohost.experiments.identify_rig")
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--first-seed", type=int, default=1)
    parser.add_argument("--out", type=Path, help="keep everything here (default: temporary)")
    parser.add_argument("--lengths", choices=("servos", "command"), default="servos")
    parser.add_argument("--until", type=float, help="s of each log fitted (default: all)")
    parser.add_argument("--segment-s", type=float, default=4.0, help="segments, s (4; 0: one)")
    parser.add_argument(
        "--fit-only", action="store_true", help="fit the recordings already in --out again"
    )
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        root = args.out or Path(tmp)
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            out = one_seed(root, seed, args)
            errs = out.pop("errors", {})
            line = "  ".join(
                f"{k} {v:+.3f}" if k.startswith("mounting") else f"{k} {100 * v:+.1f} %"
                for k, v in errs.items()
            )
            print(f"seed {seed}: {out}; {line}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
