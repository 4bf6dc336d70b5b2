"""Identification on truths nobody tuned to: drawn from a stated prior, identified by the
default command, then run with what it found.

``python -m studies.identify_heldout [--cases 10] [--out DIR] [--steps record,identify,run,replay]
[--clock real|sim] [--only K,K]``

The cases are drawn from :data:`PRIOR` with the generator seeded by :data:`HELD_OUT_SEED`, both
fixed before any tuning against this study: a method tuned until these figures pass would be
tuned to these truths, and the study would say nothing. Case ``k`` is always the same truth.

Per case, in ``DIR/caseK``, the three commands a lab runs on the shipped ``sim-rig``
configuration, the mounting taken as level and the scene's masses weighed as
docs/identification.md asks (the D-bar's motion fixes J3, stiffness and damping only against
them): the nominal D-bar with the truth's bar and wheel masses read off a scale of
:data:`SCALE_KG` resolution:

1. ``record``: ``gyrotens run --sim --config C --truth-scene T --schedule identify -o LOG``, the
   truth ``T`` the drawn D-bar, ``C`` the shipped ``sim-rig`` with the drawn IMU turn, IMU
   latency and wheel speed error in its ``[sim.truth]`` and ``[sim.wheels]`` tables;
2. ``identify``: ``gyrotens identify LOG -o IDENT.toml --overlay OVERLAY.toml --config C``,
   every option at its default;
3. ``run``: the paper's schedule on the same truth with the identified scene and overlay (the
   emulated IMU kept where the truth has it), whose summary gives the estimator's NEES;
   A recording or run whose truth did not keep real time (the machine was loaded; the run
   says not to identify from such a log) is made again, at most :data:`ATTEMPTS` times;
4. ``replay`` (not by default): the estimator of the identified scene and overlay replayed over
   the run an earlier ``run`` step recorded (``gyrotens replay``, the NEES against the
   recorded truth), for a new identification judged on the same real-time run whatever the
   machine's load is now.

With ``--clock sim`` the recording is made in process on the simulated clock instead
(:func:`gyrohost.sil.scoring.rig_model_run`: the same truth, emulators, speed error and IMU
latency, no real-time effects), so it does not depend on the machine's load; the ``run`` step
then is left out (its NEES is the real-time rig's).

It prints per case the truth's factors, each parameter's error and reported 1-sigma, the
identification's wall and CPU time and the run's NEES with the share of its samples inside their
bounds; then per parameter how often the error is within the acceptance tolerance
(:data:`TOLERANCE`), within 1 and 2 reported sigmas. The rig runs are real time: run on a
quiet machine (each case takes about a minute plus the identification).
"""

import argparse
import resource
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomllib

from gyrohost.resources import shipped
from gyrohost.run.log import read_meta
from gyrohost.run.summary import real_time_lost
from studies.identify_rig import (
    gyrotens,
    seeded_sim_rig,
    truth_kept_overlay,
)

HELD_OUT_SEED = 20261129
"""Seeds the draw of the truths; fixed with :data:`PRIOR` before the study was first run."""

PRIOR = {
    "J3": (0.7, 1.3),
    "bar_mass": (0.7, 1.3),
    "wheel_mass": (0.7, 1.3),
    "stiffness": (0.7, 1.3),
    "damping": (0.7, 1.3),
    "imu_rotation_deg": (-3.0, 3.0),
    "imu_latency_s": (0.0, 0.020),
    "speed_error_std_rad_s": (0.0, 0.02),
}
"""Uniform ranges: factors on the shipped D-bar's wheel J3, bar and wheel masses, string
stiffness and damping; the IMU's turn from level about each axis, deg; the IMU's latency, s;
the wheels' speed-loop error, rad/s."""

SCALE_KG = 0.001
"""A kitchen scale's resolution: the weighed masses are the truth's rounded to it."""

TOLERANCE = {"J3": 0.03, "stiffness": 0.10, "damping": 0.25, "mounting": 0.5}
"""The acceptance: relative for J3, stiffness and damping; degrees for each mounting axis."""

NOMINAL = {"J3": 0.5 * 0.050 * 0.031**2, "stiffness": 200.0, "damping": 2.0}
"""The shipped D-bar's wheel J3 (kg m^2), string stiffness (N/m) and damping (N s/m)."""

STEPS = ("record", "identify", "run", "replay")
ATTEMPTS = 3
"""Real-time runs made for one log at most (:func:`real_time_run`)."""


@dataclass(frozen=True)
class Truth:
    """One drawn truth: the factors on the shipped D-bar and the rig's drawn imperfections."""

    factors: dict
    imu_rotation_deg: tuple[float, float, float]
    imu_latency_s: float
    speed_error_std_rad_s: float


def draw_truths(n: int) -> list[Truth]:
    """The first ``n`` truths of :data:`PRIOR` (the same for every ``n`` up to the count)."""
    rng = np.random.default_rng(HELD_OUT_SEED)
    truths = []
    for _ in range(n):
        factors = {k: float(rng.uniform(*PRIOR[k])) for k in ("J3", "bar_mass", "wheel_mass",
                                                               "stiffness", "damping")}  # fmt: skip
        rotation = tuple(float(a) for a in rng.uniform(*PRIOR["imu_rotation_deg"], size=3))
        latency = float(rng.uniform(*PRIOR["imu_latency_s"]))
        speed_error = float(rng.uniform(*PRIOR["speed_error_std_rad_s"]))
        truths.append(Truth(factors, rotation, latency, speed_error))
    return truths


def _with_masses(text: str, bar_kg: float, wheel_kg: float) -> str:
    """The shipped D-bar scene's text with every bar's and wheel's mass replaced."""
    text = text.replace("mass = 0.10", f"mass = {bar_kg!r}")
    return text.replace("mass = 0.050", f"mass = {wheel_kg!r}")


def write_case(folder: Path, truth: Truth, seed: int) -> tuple[Path, Path]:
    """The truth scene, the lab's weighed nominal scene and the host's configuration of
    ``truth`` in ``folder`` (the emulated devices' noise seeded with ``seed``): (config, truth
    scene)."""
    f = truth.factors
    shipped_text = Path(shipped("scene", "dbar-gyro")).read_text()
    bar_kg, wheel_kg = 0.10 * f["bar_mass"], 0.050 * f["wheel_mass"]
    text = _with_masses(shipped_text.replace('"dbar-gyro"', '"truth"'), bar_kg, wheel_kg)
    text = text.replace("spin = ", f"J3 = {NOMINAL['J3'] * f['J3']!r}, spin = ")
    text = text.replace("stiffness = 200.0", f"stiffness = {200.0 * f['stiffness']!r}")
    text = text.replace("damping = 2.0", f"damping = {2.0 * f['damping']!r}")
    (folder / "truth.toml").write_text(text)
    weighed = [round(m / SCALE_KG) * SCALE_KG for m in (bar_kg, wheel_kg)]
    nominal = _with_masses(shipped_text.replace('"dbar-gyro"', '"weighed"'), *weighed)
    (folder / "weighed.toml").write_text(nominal)
    config = seeded_sim_rig(seed, truth.speed_error_std_rad_s)
    config = config.replace('scene = "dbar-gyro"', 'scene = "weighed.toml"', 1)
    rotation = ", ".join(repr(a) for a in truth.imu_rotation_deg)
    config += (
        f'\n[sim.truth]\nscene = "truth.toml"\nimu_rotation_deg = [{rotation}]\n'
        f"imu_latency_s = {truth.imu_latency_s!r}\n"
    )
    (folder / "rig.toml").write_text(config)
    return folder / "rig.toml", folder / "truth.toml"


def errors(truth: Truth, ident: Path, overlay: Path) -> dict[str, tuple[float, float]]:
    """Parameter -> (error, reported 1-sigma): relative for J3, stiffness and damping, degrees
    for each mounting axis; a parameter the fit left undetermined has sigma inf."""
    from gyrohost.ident.report import read_identified

    text = ident.read_text()
    scene, reported = tomllib.loads(text), read_identified(text)
    wheel, string = scene["bars"][0]["wheel"], scene["strings"][0]
    got = {
        "J3": wheel.get("J3", 0.5 * wheel["mass"] * wheel["radius"] ** 2),
        "stiffness": string["stiffness"],
        "damping": string["damping"],
    }
    out = {}
    for name, nominal in NOMINAL.items():
        true = nominal * truth.factors[name]
        sigma = reported.get(name, (0.0, np.inf))[1]
        out[name] = (got[name] / true - 1.0, sigma / true)
    rpy = np.degrees(tomllib.loads(overlay.read_text())["imu"]["mounting_rpy_rad"])
    for axis, value, true in zip(
        ("roll", "pitch", "yaw"), rpy, truth.imu_rotation_deg, strict=True
    ):
        sigma = np.degrees(reported.get(f"mounting.{axis}", (0.0, np.inf))[1])
        out[f"mounting.{axis}"] = (float(value - true), float(sigma))
    return out


def record_simulated_clock(config: Path, seed: int, log: Path) -> int:
    """The identification schedule played in process on the simulated clock on the rig of
    ``config`` (its ``[sim.truth] scene`` the truth), written as a run log: exit status 0."""
    from gyrohost.config import load_rig_config
    from gyrohost.control.schedule import load_schedule
    from gyrohost.ident.simcheck import write_log
    from gyrohost.sil.scoring import rig_model_run

    schedule = load_schedule(shipped("schedule", "identify"))
    rig = load_rig_config(config)
    _, data, *_ = rig_model_run(rig, seed, schedule.t_end, schedule=schedule)
    write_log(data, log)
    return 0


def one_case(root: Path, k: int, truth: Truth, steps, clock: str = "real") -> dict:
    """The ``steps`` of case ``k`` in ``root/caseK``, recorded on the ``clock``; what they
    gave."""
    folder = root / f"case{k}"
    folder.mkdir(parents=True, exist_ok=True)
    config, scene = folder / "rig.toml", folder / "truth.toml"
    ident, overlay, log = folder / "ident.toml", folder / "overlay.toml", folder / "ident-run"
    rig = ["--sim", "--config", str(config), "--truth-scene", str(scene)]
    out = {}
    if "record" in steps:
        write_case(folder, truth, seed=k)
        if clock == "sim":
            out["record"] = record_simulated_clock(config, k, log)
        else:
            argv = ["run", *rig, "--schedule", "identify"]
            out["record"], out["record_real_time"] = real_time_run(argv, log)
    if out.get("record", 0) != 0:
        return out  # a recording cut short (a loaded machine): nothing to identify
    if "identify" in steps:
        t0, cpu0 = time.perf_counter(), _children_cpu_s()
        argv = ["identify", str(log), "-o", str(ident), "--overlay", str(overlay)]
        out["identify"] = gyrotens([*argv, "--config", str(config)])
        out["identify_s"] = time.perf_counter() - t0
        out["identify_cpu_s"] = _children_cpu_s() - cpu0
    if not ident.exists():
        return out
    out["errors"] = errors(truth, ident, overlay)
    if "run" in steps and clock == "real":
        kept = truth_kept_overlay(overlay, folder / "run-overlay.toml", truth.imu_rotation_deg)
        argv = ["run", *rig, "--overlay", str(kept), "--scene", str(ident)]
        out["run"], out["run_real_time"] = real_time_run(argv, folder / "with-ident")
        if out["run"] == 0:
            out["nees"] = read_meta(folder / "with-ident")["summary"]["estimator"]["nees"]
    if "replay" in steps and (folder / "with-ident").is_dir():
        out["nees"] = replayed_nees(folder / "with-ident", ident, config, overlay)
    return out


def real_time_run(argv: list[str], log: Path) -> tuple[int, str]:
    """``gyrotens ARGV -o LOG`` on the real-time simulated rig, made again (at most
    :data:`ATTEMPTS` times in all) while its truth did not keep real time: such a log's stamps
    and physics disagree, and the run says not to identify from it (a loaded machine). Its exit
    status, and how real time went (``kept``, ``kept at attempt K``, ``lost``)."""
    for attempt in range(1, ATTEMPTS + 1):
        if log.exists():
            shutil.rmtree(log)
        status = gyrotens([*argv, "-o", str(log)])
        if status != 0 or real_time_lost(read_meta(log).get("summary", {})) is None:
            return status, "kept" if attempt == 1 else f"kept at attempt {attempt}"
        print(f"{log}: the truth did not keep real time (attempt {attempt} of {ATTEMPTS})")
    return status, "lost"


def replayed_nees(run: Path, ident: Path, config: Path, overlay: Path) -> dict:
    """The NEES table (:meth:`gyrohost.run.health.TruthScore.table`) of the estimator a run with
    ``ident`` and ``overlay`` on ``config`` has, replayed over the recorded ``run``."""
    from gyrohost.config import load_rig_config
    from gyrohost.estimator.config import for_rig
    from gyrohost.run.replay import replay

    est = for_rig(load_rig_config(config, [overlay]))
    with tempfile.TemporaryDirectory() as tmp:
        return replay(run, Path(tmp) / "replay", ident, est)["nees"]


def nees_inside(nees: dict) -> bool:
    """Whether a run's NEES ``mean`` lies within the one-sample 95 % bounds of its ``dof``: the
    acceptance's test (a mean over a run of strongly correlated samples varies almost as much
    as one sample does)."""
    low, high = nees["sample_bounds95"]
    return bool(low <= nees["mean"] <= high)


def within(name: str, error: float) -> bool:
    """Whether ``error`` of parameter ``name`` meets :data:`TOLERANCE`."""
    return abs(error) <= TOLERANCE["mounting" if name.startswith("mounting") else name]


def summary_lines(rows: list[dict]) -> list[str]:
    """Per parameter: cases within the tolerance, within 1 and 2 reported sigmas."""
    lines = [f"{'parameter':<16}{'tolerance':>10}{'in tolerance':>14}{'<= 1 sigma':>12}"
             f"{'<= 2 sigma':>12}{'max |error|':>13}"]  # fmt: skip
    for name in dict.fromkeys(k for r in rows for k in r):
        errs = [r[name] for r in rows if name in r]
        n = len(errs)
        tol = TOLERANCE["mounting" if name.startswith("mounting") else name]
        inside = sum(within(name, e) for e, _ in errs)
        one = sum(abs(e) <= s for e, s in errs)
        two = sum(abs(e) <= 2 * s for e, s in errs)
        worst = max(abs(e) for e, _ in errs)
        lines.append(f"{name:<16}{tol:>10g}{f'{inside}/{n}':>14}{f'{one}/{n}':>12}"
                     f"{f'{two}/{n}':>12}{worst:>13.3g}")  # fmt: skip
    return lines


def _children_cpu_s() -> float:
    """User and system CPU time of the ended child processes so far, s: what the
    identification costs whatever else loads the machine (its wall time depends on that)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def case_line(k: int, truth: Truth, out: dict) -> str:
    f = " ".join(f"{name} x{v:.2f}" for name, v in truth.factors.items())
    rot = ", ".join(f"{a:+.2f}" for a in truth.imu_rotation_deg)
    head = (f"case {k}: {f}; IMU turned ({rot}) deg, latency {1e3 * truth.imu_latency_s:.1f} "
            f"ms, speed error {truth.speed_error_std_rad_s:.3f} rad/s")  # fmt: skip
    errs = "  ".join(
        f"{name} {e:+.2f} deg ({s:.2f})" if name.startswith("mounting")
        else f"{name} {100 * e:+.1f} % ({100 * s:.1f})"
        for name, (e, s) in out.get("errors", {}).items()
    )  # fmt: skip
    status = {k: v for k, v in out.items() if k in STEPS}
    if status.get("record", 0) != 0:
        return f"{head}\n  the recording stopped (exit {status['record']}): not identified"
    figures = (f"exit {status}; identify {out.get('identify_s', float('nan')):.0f} s "
               f"({out.get('identify_cpu_s', float('nan')):.0f} s of CPU)")  # fmt: skip
    for step in ("record", "run"):
        if out.get(f"{step}_real_time", "kept") != "kept":
            figures += f"; {step}: real time {out[f'{step}_real_time']}"
    if "nees" in out:
        n = out["nees"]
        low, high = n["sample_bounds95"]
        verdict = "inside" if nees_inside(n) else "OUTSIDE"
        figures += (f"; NEES {n['mean']:.1f} {verdict} [{low:.1f}, {high:.1f}] (dof {n['dof']}), "
                    f"{100 * n['inside']:.0f} % of samples inside")  # fmt: skip
    return f"{head}\n  error (1-sigma): {errs}\n  {figures}"


def _steps(text: str) -> tuple[str, ...]:
    steps = tuple(s for s in text.split(",") if s)
    if unknown := [s for s in steps if s not in STEPS]:
        raise argparse.ArgumentTypeError(f"unknown step(s) {unknown}: choose from {STEPS}")
    return steps


def _case_numbers(text: str) -> set[int]:
    try:
        return {int(k) for k in text.split(",") if k}
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give case numbers, e.g. 3,4") from None


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m studies.identify_heldout")
    parser.add_argument("--cases", type=int, default=10, help="truths drawn (10)")
    parser.add_argument("--out", type=Path, help="keep everything here (default: temporary)")
    parser.add_argument(
        "--steps", type=_steps, default=STEPS[:3],
        help="comma-separated, of record,identify,run,replay (default record,identify,run; "
        "the others reuse --out)",
    )  # fmt: skip
    parser.add_argument(
        "--clock", choices=("real", "sim"), default="real",
        help="record on the real-time simulated rig (default) or in process on the simulated "
        "clock (no run step)",
    )  # fmt: skip
    parser.add_argument(
        "--only", type=_case_numbers, metavar="K,K",
        help="these of the drawn cases only (e.g. those a loaded machine spoiled; default all)",
    )  # fmt: skip
    args = parser.parse_args(argv)
    rows, nees = [], []
    with tempfile.TemporaryDirectory() as tmp:
        root = args.out or Path(tmp)
        for k, truth in enumerate(draw_truths(args.cases), start=1):
            if args.only and k not in args.only:
                continue
            out = one_case(root, k, truth, args.steps, args.clock)
            rows += [out["errors"]] if "errors" in out else []
            nees += [nees_inside(out["nees"])] if "nees" in out else []
            print(case_line(k, truth, out), flush=True)
    if rows:
        print("\n".join(summary_lines(rows)))
    if nees:
        print(f"run's NEES inside its bounds: {sum(nees)}/{len(nees)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
