"""Identification on the real-time simulated rig, end to end, through the commands a lab uses.

``python -m studies.identify_rig [--seeds 1] [--first-seed 1] [--out DIR]
[--speed-error RAD_S] [--method output|filter] [--workers N] [--lengths servos] [--until S]
[--segment-s S] [--sil-runs 10] [--steps record,identify,run]``

Per seed (the simulated IMU's noise and biases, the wheels' speed error and the servos' holds):

1. ``record``: ``gyrotens run --sim --config C --truth-scene T --schedule identify -o LOG``: the
   truth ``T`` is the shipped D-bar with J3 x 1.3, bar mass x 0.8, string stiffness x 1.25 and
   damping x 0.7; ``C`` is ``sim-rig`` with the bars weighed (its scene: the shipped D-bar with
   the truth's bar mass), the truth's IMU turned (3, -1.7, 1.1) degrees from where ``C`` says
   it is (``[sim.truth] imu_rotation_deg``) and the emulated wheels erring from their
   setpoints by ``--speed-error`` (0 by default: the acceptance's exact wheels; a real speed
   loop errs by about 0.01 rad/s);
2. ``identify``: ``gyrotens identify LOG -o IDENT.toml --config C --overlay OVERLAY.toml``
   with ``--method`` (the output error in ``--segment-s`` multiple-shooting segments, or the
   filter's prediction error) over the whole log or its first ``--until`` seconds;
3. ``run``: ``gyrotens run --sim --config C --truth-scene T --overlay RUN.toml --scene
   IDENT.toml`` (the lab's third command, on the paper's schedule), ``RUN.toml`` the fit's
   ``OVERLAY.toml`` with the truth's IMU kept where it was (:func:`truth_kept_overlay`:
   ``[sim.truth] imu_rotation_deg`` turns the emulated IMU from where the configuration says
   it is, and the overlay moves that to the identified mounting); then the estimator's
   consistency against the same truth, ``gyrotens sil --realtime --runs N`` (``--sil-runs``,
   10 by default; 0: none) with the nominal scene and mounting and with the identified ones.

It prints each identified figure's error against the truth with its reported 1-sigma (J3,
stiffness and damping relative, the mounting in degrees; over several seeds, the coverage
table of :func:`~gyrohost.ident.simcheck.coverage_lines`), the fit's wall time,
the exit status of every command, the third command's figures (the NEES with the share of its
samples inside their own bounds, the NIS against the bounds of the run's average, the tilt's
error at its end: :func:`estimator_figures`), and the two SILs' NEES, NIS and tilt lines
against the bounds of an N-run average. The rig runs are real time: run this at normal
priority on a quiet machine.
"""

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import tomllib

from gyrohost.ident.report import read_identified
from gyrohost.ident.simcheck import (
    FACTORS,
    IMU_ROTATION_DEG,
    coverage_lines,
    wheel_speed_error,
)
from gyrohost.resources import shipped

J3_NOMINAL = 0.5 * 0.050 * 0.031**2  # the shipped D-bar's wheel disc, kg m^2


STEPS = ("record", "identify", "run")


def write_rig_files(
    folder: Path, seed: int = 1, speed_error_rad_s: float = 0.0
) -> tuple[Path, Path]:
    """The host's configuration ``C`` (bars weighed; the simulated IMU, wheels and servos
    seeded with ``seed``; the wheels erring from their setpoints by ``speed_error_rad_s``) and
    the truth scene ``T`` in ``folder``.

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
    config = seeded_sim_rig(seed, speed_error_rad_s)
    config = config.replace('scene = "dbar-gyro"', 'scene = "weighed.toml"')
    rotation = ", ".join(repr(a) for a in IMU_ROTATION_DEG)
    config += f"\n[sim.truth]\nimu_rotation_deg = [{rotation}]\n"
    (folder / "rig.toml").write_text(config)
    return folder / "rig.toml", folder / "truth.toml"


def seeded_sim_rig(seed: int, speed_error_rad_s: float) -> str:
    """The shipped ``sim-rig`` configuration's text with its emulated IMU, wheels and servos
    seeded with ``seed`` and the wheels erring from their setpoints by ``speed_error_rad_s``."""
    config = Path(shipped("config", "sim-rig")).read_text()
    config = config.replace("seed = 1\n", f"seed = {seed}\n", 1)  # [sim.imu], the first
    config = wheel_speed_error(config, speed_error_rad_s)
    for table in ("[sim.wheels]\n", "[sim.servos]\n"):
        config = config.replace(table, f"{table}seed = {seed}\n", 1)
    return config


def gyrotens(args: list[str], nice: bool = False) -> int:
    """Run ``gyrotens ARGS`` in a child process (niced if asked); its exit status."""
    cmd = [sys.executable, "-m", "gyrohost", *args]
    return subprocess.run(["nice", "-n", "19", *cmd] if nice else cmd, check=False).returncode


def identified_errors(ident: Path, overlay: Path) -> dict[str, tuple[float, float]]:
    """Parameter -> (error against the truth, reported 1-sigma) of an identified scene and
    overlay: relative for J3, stiffness and damping, degrees for each axis of the mounting (a
    parameter reported not separable has sigma inf)."""
    text = ident.read_text()
    scene, reported = tomllib.loads(text), read_identified(text)
    wheel, string = scene["bars"][0]["wheel"], scene["strings"][0]
    truth = {
        "J3": J3_NOMINAL * FACTORS["J3"],
        "stiffness": 200.0 * FACTORS["stiffness"],
        "damping": 2.0 * FACTORS["damping"],
    }
    got = {"J3": wheel["J3"], "stiffness": string["stiffness"], "damping": string["damping"]}
    out = {
        name: (got[name] / true - 1.0, reported.get(name, (0.0, np.inf))[1] / true)
        for name, true in truth.items()
    }
    rpy = np.degrees(tomllib.loads(overlay.read_text())["imu"]["mounting_rpy_rad"])
    for axis, value, true in zip(("roll", "pitch", "yaw"), rpy, IMU_ROTATION_DEG, strict=True):
        sigma = np.degrees(reported.get(f"mounting.{axis}", (0.0, np.inf))[1])
        out[f"mounting.{axis}_deg"] = (float(value - true), float(sigma))
    return out


def truth_kept_overlay(overlay: Path, out: Path, truth_deg=IMU_ROTATION_DEG) -> Path:
    """``overlay`` (what ``gyrotens identify`` wrote) with ``[sim.truth] imu_rotation_deg`` set
    so that the emulated IMU stays at the truth's mounting (``truth_deg`` from a zero mounting)
    now that the host's is the identified one, written to ``out``.

    The emulator turns the IMU by ``imu_rotation_deg`` from the configuration's mounting:
    without this the overlay would turn the truth's IMU by the identified mounting as well, and
    the run would test a rig the fit never saw."""
    from gyrohost.geometry import euler_zyx, rotation_zyx

    text = overlay.read_text()
    identified = tomllib.loads(text)["imu"]["mounting_rpy_rad"]
    turn = rotation_zyx(*np.radians(truth_deg)) @ rotation_zyx(*identified).T
    deg = ", ".join(repr(float(a)) for a in np.degrees(euler_zyx(turn)))
    out.write_text(text + f"\n[sim.truth]\nimu_rotation_deg = [{deg}]\n")
    return out


def truth_lag_s(log: Path) -> float:
    """Median lag (s) of the simulated rig's truth behind real time in the run: a loaded CPU
    makes the recording's physics lag its time stamps."""
    from gyrohost.run.log import read_stream

    truth = read_stream(log, "truth")
    return float(np.median(truth["rig_t_s"] - truth["truth_t_s"]))


def estimator_figures(log: Path) -> dict:
    """The estimator's figures of a simulated run's summary: the NEES (mean and the share of
    its samples inside their own 95 % bounds), the NIS per source (mean and whether inside the
    95 % bounds of the run's own average) and the tilt's error at the end of the schedule
    (deg)."""
    from gyrohost.run.log import read_meta

    summary = read_meta(log)["summary"]
    nees = summary["estimator"]["nees"]
    out = {"nees": (nees["mean"], nees["inside"])}
    for name, row in summary["estimator"]["nis"].items():
        low, high = row["bounds95"]
        out[name] = (row["mean"], bool(low <= row["mean"] <= high))
    tilt = summary["tilt_end_estimate_rad"] - summary["tilt_end_truth_rad"]
    out["tilt_end_error_deg"] = float(np.degrees(tilt))
    return out


def _identify_argv(log: Path, files: dict, args) -> list[str]:
    """``gyrotens identify``'s arguments for ``log`` with the options of :func:`main`."""
    argv = ["identify", str(log), "-o", str(files["ident"]), "--config", str(files["config"]),
            "--overlay", str(files["overlay"]), "--method", args.method]  # fmt: skip
    if args.method == "filter":
        argv += [] if args.workers is None else ["--workers", str(args.workers)]
    else:
        argv += ["--lengths", args.lengths, "--segment-s", str(args.segment_s)]
    return argv + ([] if args.until is None else ["--until", str(args.until)])


def one_seed(root: Path, seed: int, args) -> dict:
    """The steps ``args.steps`` of :data:`STEPS` for one seed in ``root/seedN`` (``args``: the
    options of :func:`main`; a step left out takes what an earlier call left there); what they
    gave."""
    folder = root / f"seed{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    files = {name: folder / f"{name}.toml" for name in ("truth", "ident", "overlay")}
    files["config"], log = folder / "rig.toml", folder / "ident-run"  # as write_rig_files names
    against_truth = ["--config", str(files["config"]), "--truth-scene", str(files["truth"])]
    rig = ["--sim", *against_truth]
    out = {}
    if "record" in args.steps:
        write_rig_files(folder, seed, args.speed_error)
        out["record"] = gyrotens(["run", *rig, "--schedule", "identify", "-o", str(log)])
    out["truth_lag_s"] = truth_lag_s(log)
    if "identify" in args.steps:
        t0 = time.perf_counter()
        out["identify"] = gyrotens(_identify_argv(log, files, args), nice=True)
        out["fit_s"] = time.perf_counter() - t0
    if not files["ident"].exists():
        return out
    out["errors"] = identified_errors(files["ident"], files["overlay"])
    if "run" in args.steps:
        kept = truth_kept_overlay(files["overlay"], folder / "run-overlay.toml")
        with_ident = ["--overlay", str(kept), "--scene", str(files["ident"])]
        out["run"] = gyrotens(["run", *rig, *with_ident, "-o", str(folder / "with-ident")])
        out["estimator"] = estimator_figures(folder / "with-ident")
        sils = (("nominal", []), ("identified", with_ident)) if args.sil_runs else ()
        for name, extra in sils:
            out[f"sil {name}"] = sil_figures([*against_truth, *extra], folder / f"sil-{name}", args)
    return out


def sil_figures(argv: list[str], folder: Path, args) -> list[str]:
    """The consistency lines (NEES, NIS per source, tilt) of ``gyrotens sil --realtime ARGV``
    over ``args.sil_runs`` runs of the paper's schedule, logged in ``folder``."""
    cmd = [sys.executable, "-m", "gyrohost", "sil", "--realtime", "--runs", str(args.sil_runs),
           *argv, "--out", str(folder)]  # fmt: skip
    done = subprocess.run(cmd, check=False, capture_output=True, text=True)
    if done.returncode:
        return [f"gyrotens sil exited with {done.returncode}: {done.stderr.strip()[-300:]}"]
    keep = ("[sil] NEES:", "[sil] NIS", "[sil] tilt")
    return [line for line in done.stdout.splitlines() if line.startswith(keep)]


def _steps(text: str) -> tuple[str, ...]:
    steps = tuple(s for s in text.split(",") if s)
    unknown = [s for s in steps if s not in STEPS]
    if unknown:
        raise argparse.ArgumentTypeError(f"unknown step(s) {unknown}: choose from {STEPS}")
    return steps


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m studies.identify_rig")
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--first-seed", type=int, default=1)
    parser.add_argument("--out", type=Path, help="keep everything here (default: temporary)")
    parser.add_argument(
        "--speed-error", type=float, default=0.0, help="the wheels' speed error, rad/s (0)"
    )
    parser.add_argument("--method", choices=("output", "filter"), default="output")
    parser.add_argument("--workers", type=int, help="the filter fit's processes")
    parser.add_argument("--lengths", choices=("servos", "command"), default="servos")
    parser.add_argument("--until", type=float, help="s of each log fitted (default: all)")
    parser.add_argument("--segment-s", type=float, default=4.0, help="segments, s (4; 0: one)")
    parser.add_argument(
        "--sil-runs", type=int, default=10,
        help="real-time SIL runs of the nominal and the identified scene (run step; 0: none)",
    )  # fmt: skip
    parser.add_argument(
        "--steps", type=_steps, default=STEPS,
        help="comma-separated, of record,identify,run (default all; the others reuse --out; "
        "empty: report what --out holds)",
    )  # fmt: skip
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        root = args.out or Path(tmp)
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            out = one_seed(root, seed, args)
            errs = out.pop("errors", {})
            rows += [errs] if errs else []
            sils = {k: out.pop(k) for k in [k for k in out if k.startswith("sil ")]}
            line = "  ".join(
                f"{k} {e:+.3f} ({s:.3f})" if k.startswith("mounting")
                else f"{k} {100 * e:+.1f} % ({100 * s:.1f})"
                for k, (e, s) in errs.items()
            )  # fmt: skip
            print(f"seed {seed}: {out}; error (1-sigma): {line}", flush=True)
            for name, lines in sils.items():
                print(f"  {name} ({args.sil_runs} runs):\n    " + "\n    ".join(lines), flush=True)
    if len(rows) > 1:
        print("\n".join(coverage_lines(rows, "J3, stiffness, damping relative; mounting in deg")))
    return 0


if __name__ == "__main__":
    sys.exit(main())
