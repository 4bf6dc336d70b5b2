"""An identified scene on another manoeuvre than the one it was identified from (simulated rig).

``python -m studies.identify_transfer [--seed 1] [--runs 6] [--duration 3]
[--out DIR] [--yaw-offsets RAD ...] [--preset]``

The truth of :mod:`.identify_check` (J3 x 1.3, bar mass x 0.8, string stiffness x 1.25, damping
x 0.7, the IMU mounted (3, -1.7, 1.1) degrees off) is identified from its excitation, the bars
weighed (:func:`.identify_check.write_rigs` with ``weighed``, :func:`.identify_check.record_log`,
:func:`.identify_check.identify_log`; seed ``--seed``); with ``--preset`` from the shipped
``identify`` preset as a lab records and fits it (:func:`identify_preset`). Then truth, nominal
and identified scene play the paper's schedule (:func:`gyrohost.control.presets.paper`,
``--duration`` s):

- **Prediction.** Each scene's rig model (:func:`.estimator_sil.rig_model_run` with that scene as
  the truth) under the same host commands (rest lengths through the servos' lag, wheel speeds
  through the wheel board), from the same initial state: its node coordinates against the
  truth's at every truth step (5 ms). No feedback: an open-loop prediction.
- **Filter.** The in-process SIL (:func:`.estimator_sil.sil_results`, ``--runs`` seeds from 1)
  with the truth's scene and mounting as ``[sim.truth]`` (scene, ``imu_rotation_deg``) and the
  filter's scene and ``[imu] mounting_rpy_rad`` nominal or identified, the identified mounting
  with its covariance (``imu_mounting_cov_rad2``, as ``gyrotens identify`` writes it: the
  filter estimates the mounting's error, scored against the truth's): NEES and NIS per source
  against the 95 % bounds of a ``--runs``-run average. More filters tell the shares apart: the
  identified scene and mounting with the mounting taken as exact, the nominal scene with the
  identified mounting, the identified scene with the true mounting, and the truth's own scene
  and mounting (the reference: the filter's consistency on this truth when nothing is
  mis-identified); ``--yaw-offsets``: the truth's with the mounting's yaw off by each of these
  (rad), the filter's tolerance of a mis-identified yaw.
"""

import argparse
import sys
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from gyrohost.ident.simcheck import (
    GROUPS,
    errors,
    identify_log,
    record_log,
    write_rigs,
)

IDENT_GROUPS = tuple(g for g in GROUPS if g != "bar-mass")
"""The bars are weighed (docs/identification.md): the fit leaves their mass."""


@dataclass(frozen=True)
class Rig:
    """One side of the comparison: a scene file and the IMU mounting the host believes, with
    its covariance (3, 3), rad^2, or None (exact)."""

    name: str
    scene_path: Path
    mounting_rpy_rad: tuple[float, float, float]
    mounting_cov_rad2: tuple | None = None


def paper_scene(scene, duration_s: float):
    """``scene`` with its strings playing the paper's schedule over ``duration_s`` (s)."""
    from gyrohost.control.presets import paper
    from gyrotensegrity import Model
    from gyrotensegrity.piecewise import PiecewiseLinear

    schedule = paper(Model(scene), duration_s=duration_s)

    def rest(s):
        if s.name not in schedule.names:
            return s
        column = schedule.rest_length[:, schedule.names.index(s.name)]
        return replace(s, rest_length=PiecewiseLinear(schedule.t.copy(), column.copy()))

    return replace(scene, strings=[rest(s) for s in scene.strings], duration=duration_s)


def identify(folder: Path, seed: int, duration_s: float | None = None):
    """Record the truth's excitation (seed ``seed``; ``duration_s``: cut short) and fit it from
    the weighed nominal.

    Returns
    -------
    nominal_config : Path
    truth_config : Path
    result : gyrohost.ident.fit.FitResult
    """
    nominal, truth = write_rigs(folder, duration_s, weighed=True)
    log = record_log(truth, seed, folder / "ident-log")
    return nominal, truth, identify_log(nominal, [log], IDENT_GROUPS)


def identify_preset(folder: Path, seed: int):
    """Record the shipped ``identify`` preset on the acceptance truth of :mod:`.identify_rig`
    in process (:func:`.identify_preset.record`, seed ``seed``) and fit it as ``gyrotens
    identify`` does: the servos' reports rendered by the commands, 4 s segments, the default
    groups. Returns what :func:`identify` returns; the truth's configuration is written here
    (the host's with the truth's scene and mounting)."""
    from gyrohost.ident.fit import fit
    from gyrohost.ident.groups import DEFAULT_GROUPS
    from gyrohost.ident.simcheck import fit_inputs, with_true_mounting
    from studies.identify_preset import record

    nominal, log, _ = record(folder, "identify", seed)
    truth = folder / "truth-rig.toml"
    text = nominal.read_text().replace('scene = "weighed.toml"', 'scene = "truth.toml"')
    truth.write_text(with_true_mounting(text))
    return nominal, truth, fit(*fit_inputs(nominal, [log], DEFAULT_GROUPS, 4.0, commanded=False))


def transfer_rigs(folder: Path, nominal_config: Path, truth_config: Path, result, duration_s):
    """The truth, nominal and identified rigs on the paper's schedule, scenes written in
    ``folder``. Returns (truth, [nominal, identified])."""
    from gyrohost.config import load_rig_config
    from gyrohost.ident.report import apply_result, mounting_covariance
    from gyrohost.ident.scenefile import scene_toml
    from gyrotensegrity import load_scene

    def written(name, scene):
        path = folder / f"{name}-paper.toml"
        path.write_text(scene_toml(scene))
        return path

    nominal_cfg, truth_cfg = load_rig_config(nominal_config), load_rig_config(truth_config)
    nominal = paper_scene(load_scene(nominal_cfg.scene_path), duration_s)
    found = apply_result(replace(result, scene=nominal), nominal_cfg)
    truth = Rig(
        "truth",
        written("truth", paper_scene(load_scene(truth_cfg.scene_path), duration_s)),
        tuple(truth_cfg.imu.mounting_rpy_rad),
    )
    return truth, [
        Rig("nominal", written("nominal", nominal), tuple(nominal_cfg.imu.mounting_rpy_rad)),
        Rig(
            "identified",
            written("identified", found.scene),
            tuple(found.mounting_rpy_rad),
            tuple(map(tuple, mounting_covariance(result))),
        ),
    ]


def sil_config(base, host: Rig, truth: Rig):
    """``base`` with the host's scene and mounting of ``host`` and the truth's scene and true
    mounting of ``truth`` (``[sim.truth] imu_rotation_deg``: the turn from the host's mounting
    to the true one)."""
    from gyrohost.geometry import euler_zyx, rotation_zyx
    from gyrohost.simrig.config import with_sim_keys, with_truth_scene

    turn = rotation_zyx(*truth.mounting_rpy_rad) @ rotation_zyx(*host.mounting_rpy_rad).T
    config = replace(
        base,
        scene=str(host.scene_path),
        imu=replace(base.imu, mounting_rpy_rad=host.mounting_rpy_rad),
    )
    config = with_truth_scene(config, truth.scene_path)
    rotation_deg = [float(a) for a in np.degrees(euler_zyx(turn))]
    return with_sim_keys(config, "truth", imu_rotation_deg=rotation_deg)


def node_tracks(base, host: Rig, scene_path: Path, seed: int, duration_s: float) -> np.ndarray:
    """Node positions of ``scene_path``'s rig model under ``host``'s commands at every truth
    step: shape (k, 3, n), m."""
    from gyrohost.sil.scoring import rig_model_run

    config = sil_config(base, host, Rig("prediction", scene_path, host.mounting_rpy_rad))
    model, _, truth_x, *_ = rig_model_run(config, seed, duration_s)
    # a filter state leads with the model state's node coordinates and velocities
    return np.array([model.nodes(x)[0] for x in truth_x])


def prediction_errors(base, truth: Rig, rigs, seed: int, duration_s: float) -> dict:
    """Rig name -> (max |error| of node z, max |error| of any node coordinate, RMS over all
    coordinates and steps) of its open-loop prediction against the truth, m."""
    host = rigs[0]  # every scene plays the same schedule: the host's commands are the same
    true = node_tracks(base, host, truth.scene_path, seed, duration_s)
    out = {}
    for rig in rigs:
        err = node_tracks(base, host, rig.scene_path, seed, duration_s) - true
        out[rig.name] = (
            float(np.abs(err[:, 2, :]).max()),
            float(np.abs(err).max()),
            float(np.sqrt(np.mean(err**2))),
        )
    return out


def filter_figures(base, truth: Rig, host: Rig, runs: int, duration_s: float) -> dict:
    """The SIL's :func:`~.montecarlo.summarise` figures of a filter on ``host``'s scene and
    mounting against ``truth``, ``runs`` seeds from 1."""
    from gyrohost.sil.montecarlo import summarise
    from gyrohost.sil.scoring import sil_results

    keys = (
        {} if host.mounting_cov_rad2 is None else {"imu_mounting_cov_rad2": host.mounting_cov_rad2}
    )
    results = sil_results(sil_config(base, host, truth), runs, duration_s, keys=keys)
    return summarise(results, f"[{host.name}] ")


def _yawed(rig: Rig, offset_rad: float) -> tuple[float, float, float]:
    roll, pitch, yaw = rig.mounting_rpy_rad
    return (roll, pitch, yaw + offset_rad)


def print_tables(prediction: dict, filters: dict) -> None:
    """The prediction errors, then every filter's NEES and NIS against their bounds."""
    print(f"\n{'prediction (mm)':<36}{'max |z| error':>14}{'max |error|':>13}{'RMS error':>11}")
    for name, (z, worst, rms) in prediction.items():
        print(f"{name:<36}{1e3 * z:14.2f}{1e3 * worst:13.2f}{1e3 * rms:11.2f}")
    first = next(iter(filters.values()))
    keys = [k for k in first if isinstance(first[k], dict) and "dof" in first[k]]
    names = {"nees": "NEES", "nees_after_burn_in": "NEES>0.2s"}
    head = [f"{names.get(k, k.removeprefix('nis_'))} ({first[k]['dof']})" for k in keys]
    print(f"\n{'filter':<36}" + "".join(f"{h:>16}" for h in head) + f"{'tilt RMS deg':>14}")
    for name, f in filters.items():
        row = "".join(f"{f[k]['mean']:16.2f}" for k in keys)
        print(f"{name:<36}{row}{f['tilt_rms_deg']:14.4f}")
    bounds = [f"[{first[k]['lo']:.2f}, {first[k]['hi']:.2f}]" for k in keys]
    label = f"95 % bounds ({first['runs']} runs)"
    print(f"{label:<36}" + "".join(f"{b:>16}" for b in bounds))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m studies.identify_transfer")
    parser.add_argument("--seed", type=int, default=1, help="of the identification run")
    parser.add_argument("--runs", type=int, default=6, help="SIL runs per filter (seeds 1...)")
    parser.add_argument("--duration", type=float, default=3.0, help="of the paper's schedule, s")
    parser.add_argument("--out", type=Path, help="keep scenes and log here (default: temporary)")
    parser.add_argument(
        "--preset",
        action="store_true",
        help="identify from the shipped identify preset (19.7 s, the servos' reports) instead "
        "of the 5 s excitation with commanded lengths",
    )
    parser.add_argument(
        "--yaw-offsets",
        type=float,
        nargs="*",
        default=[],
        metavar="RAD",
        help="more filters: the truth's scene and mounting but the yaw off by these, rad",
    )
    args = parser.parse_args(argv)
    from gyrohost.config import load_rig_config
    from gyrohost.ident.report import report_lines

    with tempfile.TemporaryDirectory() as tmp:
        root = args.out or Path(tmp)
        root.mkdir(parents=True, exist_ok=True)
        found = identify_preset if args.preset else identify
        nominal_config, truth_config, result = found(root, args.seed)
        print("\n".join(report_lines(result)))
        for name, (error, sigma) in errors(result, weighed=True).items():
            print(f"error against the truth: {name} {error:+.5f} (1-sigma {sigma:.5f})")
        truth, rigs = transfer_rigs(root, nominal_config, truth_config, result, args.duration)
        base = load_rig_config(nominal_config)
        prediction = prediction_errors(base, truth, rigs, args.seed, args.duration)
        nominal, identified = rigs
        hosts = (  # the two mixed rows tell the mounting's share from the scene's
            nominal,
            Rig(
                "nominal scene, identified mounting",
                nominal.scene_path,
                identified.mounting_rpy_rad,
            ),
            identified,
            replace(identified, name="identified, mounting taken as exact", mounting_cov_rad2=None),
            Rig("identified scene, true mounting", identified.scene_path, truth.mounting_rpy_rad),
            truth,
            *(
                Rig(f"truth, mounting yaw {d:+.1e} rad", truth.scene_path, _yawed(truth, d))
                for d in args.yaw_offsets
            ),
        )
        filters = {h.name: filter_figures(base, truth, h, args.runs, args.duration) for h in hosts}
    print_tables(prediction, filters)
    return 0


if __name__ == "__main__":
    sys.exit(main())
