"""``gyrotens demo [-o DIR]``: the paper's D-bar experiment end to end on the simulated rig.

Two runs of the paper's schedule (string n1-n3 shortened to 1/3 in 3 s) on the simulated rig in
real time, with the wheels at 715 rpm (``dbar-gyro``) and at rest (``dbar-nospin``): each a full
``gyrotens run --sim`` (connect, spin-up, schedule, estimator, safe state) with its log and
figures, then a side-by-side figure of node z (Fig. 7(a) against 7(b)) and a summary.
"""

import json
import shutil
import sys
import time
from pathlib import Path

RUNS = (("gyro", "dbar-gyro.toml", "wheels at 715 rpm"), ("nospin", "dbar-nospin.toml", "no spin"))
DEFAULT_CONFIG = "sim-rig"


def register(sub) -> None:
    p = sub.add_parser("demo", help="run the paper's D-bar experiment and write logs and plots")
    p.add_argument("-o", "--out", type=Path, default=Path("out/demo"), help="output folder")
    p.add_argument(
        "--config",
        default=DEFAULT_CONFIG,
        help=f"simulated rig configuration, file or shipped name (default {DEFAULT_CONFIG}); "
        "scenes from its scene's folder, else the shipped ones",
    )
    p.add_argument(
        "--duration",
        type=float,
        default=3.0,
        help="schedule duration, s (the paper's 3 s; at least 2 s for the servo speed limit)",
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from gyrohost.commands.errors import CliError
    from gyrohost.commands.run import Progress
    from gyrohost.config import ConfigError, load_rig_config
    from gyrohost.control.presets import paper
    from gyrohost.plots.log import plot_compare, plot_log
    from gyrohost.resources import ResourceError, resolve
    from gyrohost.run import ScheduleRefused, run_simulated
    from gyrohost.run.errors import LogError
    from gyrohost.run.log import check_output_folder
    from gyrotensegrity import Model, load_scene

    start = time.monotonic()
    try:
        config = load_rig_config(resolve("config", args.config))
        scenes = [resolve("scene", name, config.scene_path.parent) for _, name, _ in RUNS]
        check_output_folder(args.out)
    except (ConfigError, ResourceError, LogError) as exc:
        raise CliError(str(exc)) from None
    args.out.mkdir(parents=True, exist_ok=True)
    results = {}
    for (key, _, label), scene in zip(RUNS, scenes, strict=True):
        folder = args.out / key
        if (folder / "meta.json").exists():
            shutil.rmtree(folder)  # the previous demo's log
        schedule = paper(Model(load_scene(scene)), duration_s=args.duration)
        progress = Progress(f"{key:<7}")
        try:
            result = run_simulated(
                config, schedule, folder, scene=scene, progress=progress, meta={"demo": label}
            )
        except (ScheduleRefused, LogError) as exc:
            raise CliError(str(exc)) from None
        finally:
            progress.close()
        if result.exit_status:
            print(f"demo: the {label} run stopped: {result.reason}", file=sys.stderr)
            return result.exit_status
        plot_log(folder, folder / "plots")
        results[key] = summarise(folder, label)
    figure = plot_compare(
        [args.out / key for key, _, _ in RUNS], [label for _, _, label in RUNS],
        args.out / "fig7-spin-vs-nospin.png",
    )  # fmt: skip
    wall_s = time.monotonic() - start
    write_summary(args.out, results, wall_s)
    print(f"demo finished in {wall_s:.0f} s; outputs in {args.out}/:")
    print(f"  {figure.name}        node z with and without spin (estimate and truth)")
    for key, _, label in RUNS:
        print(
            f"  {key}/            log of the run with {label} (docs/run.md); plots in {key}/plots/"
        )
    print("  summary.md, summary.json   tilt, peak node z, rates, loop jitter")
    return 0


def summarise(folder: Path, label: str) -> dict:
    """Figures of one demo run from its log: tilts, peak n1/n3 z, rates, loop timing."""
    import numpy as np

    from gyrohost.run import jitter_line
    from gyrohost.run.log import read_meta, read_stream

    summary = read_meta(folder)["summary"]
    events = read_stream(folder, "events")
    t_land = float(events["t_s"][events["message"] == "settle"][0])  # the schedule's end
    t_end = float(events["t_s"][events["kind"] == "safe_state"][0])
    out = {
        "label": label,
        "reason": summary["reason"],
        "t_schedule_end_s": t_land,
        "loop": jitter_line(summary["loop"]),
        "rig": summary.get("rig", []),
    }
    for name, key in (("nodes", "estimate"), ("truth", "truth")):
        s = read_stream(folder, name)
        out[f"tilt_end_{key}_deg"] = float(np.degrees(np.interp(t_land, s["t_s"], s["tilt_rad"])))
        s = s[s["t_s"] <= t_end]
        if name == "truth":
            out["truth_behind_s"] = float(np.max(s["rig_t_s"] - s["truth_t_s"]))
        out[f"peak_z_cm_{key}"] = {
            n: float(100 * np.max(np.abs(s[f"{n}_z_m"]))) for n in ("n1", "n3")
        }
    duration = summary["duration_s"]
    out["rates_per_s"] = {
        name: round(rows / duration, 1)
        for name, rows in summary["rows"].items()
        if name in ("imu", "wheels", "servos", "estimate", "truth")
    }
    return out


def write_summary(out: Path, results: dict, wall_s: float) -> None:
    """``summary.json`` (everything) and ``summary.md`` (a table and the timing lines)."""
    (out / "summary.json").write_text(json.dumps({"wall_s": wall_s, **results}, indent=2) + "\n")
    lines = [
        "# gyrotens demo: the paper's D-bar experiment on the simulated rig",
        "",
        f"Wall time {wall_s:.0f} s. Tilt of the D-bar plane at the end of the schedule; "
        "peak |z| of n1 and n3 from the start to the safe state.",
        "",
        "| run | tilt estimate (deg) | tilt truth (deg) | peak z n1/n3 estimate (cm) "
        "| peak z n1/n3 truth (cm) |",
        "|---|---|---|---|---|",
    ]
    for r in results.values():
        pe, pt = r["peak_z_cm_estimate"], r["peak_z_cm_truth"]
        lines.append(
            f"| {r['label']} | {r['tilt_end_estimate_deg']:+.2f} | "
            f"{r['tilt_end_truth_deg']:+.2f} | {pe['n1']:.2f} / {pe['n3']:.2f} | "
            f"{pt['n1']:.2f} / {pt['n3']:.2f} |"
        )
    lines.append("")
    for r in results.values():
        if r["truth_behind_s"] > 0.1:
            lines += [
                f"Note ({r['label']}): the rig's truth fell behind its devices by up to "
                f"{r['truth_behind_s']:.2f} s (a loaded CPU) while the servos moved on wall time; "
                "estimate and truth may then differ by more than the estimator's own error.",
                "",
            ]
    for r in results.values():
        rates = ", ".join(f"{k} {v:g}/s" for k, v in r["rates_per_s"].items())
        lines += [f"**{r['label']}**: {r['loop']}; rows: {rates}", ""]
        lines += [f"- {line}" for line in r["rig"]] + [""]
    (out / "summary.md").write_text("\n".join(lines))
