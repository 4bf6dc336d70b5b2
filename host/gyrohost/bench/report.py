"""Markdown report, JSON and plots of a benchmark run."""

import json
import os
import platform

import numpy as np


def _f(x, fmt=".2e"):
    return "-" if x is None else format(x, fmt)


def _us(seconds):
    return "not built" if seconds is None else f"{seconds * 1e6:.2f} us"


def machine() -> dict:
    import scipy

    info = {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "cpu": platform.processor() or platform.machine(),
        "cores": os.cpu_count(),
        "load_avg_1_5_15": list(os.getloadavg()),
    }
    try:
        with open("/proc/cpuinfo") as fh:
            names = [ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")]
        info["cpu"] = names[0] if names else info["cpu"]
    except OSError:
        pass
    try:
        import mujoco

        info["mujoco"] = mujoco.__version__
    except ImportError:
        info["mujoco"] = None
    return info


def write_json(path, data):
    def default(o):
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
        raise TypeError(type(o))

    path.write_text(json.dumps(data, indent=1, default=default))


def plots(out_dir, data) -> list:
    """Pareto (node error against wall time per simulated second) and scaling plots."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []
    for i, case in enumerate(dict.fromkeys(r["case"] for r in data["trade"])):
        fig, ax = plt.subplots(figsize=(7, 4.5))
        rows = [r for r in data["trade"] if r["case"] == case and not r["failure"]]
        for method in dict.fromkeys(r["method"] for r in rows):
            for main, marker in ((True, "o"), (False, "x")):
                pts = [r for r in rows if r["method"] == method and r["main"] == main]
                if pts:
                    ax.loglog(
                        [r["wall_per_sim_s"] for r in pts],
                        [max(r["node_error_m"], 1e-16) for r in pts],
                        marker,
                        label=f"{method}{'' if main else ' (other variants)'}",
                    )
        for cls in (1e-3, 1e-6, 1e-9):
            ax.axhline(cls, color="grey", lw=0.5, ls=":")
        ax.set_xlabel("wall time per simulated second, s")
        ax.set_ylabel("max node error vs tight reference, m")
        ax.set_title(case)
        ax.legend(fontsize=7)
        fig.tight_layout()
        name = f"pareto-{i}.png"
        fig.savefig(out_dir / name, dpi=110)
        plt.close(fig)
        files.append(name)
    if data.get("scaling"):
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for joined in (False, True):
            rows = [r for r in data["scaling"] if r["joined"] == joined]
            tag = "class-2" if joined else "class-1"
            bars = [r["bars"] for r in rows]
            ax.loglog(bars, [r["fast"] * 1e6 for r in rows], "o-", label=f"fast rhs {tag}")
            ax.loglog(
                bars, [r["reference"] * 1e6 for r in rows], "x--", label=f"reference rhs {tag}"
            )
            ax.loglog(bars, [r["rk4_step"] * 1e6 for r in rows], "s:", label=f"RK4 step {tag}")
        ax.set_xlabel("bars")
        ax.set_ylabel("cost, us")
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out_dir / "scaling.png", dpi=110)
        plt.close(fig)
        files.append("scaling.png")
    return files


def markdown(data, files) -> str:
    lines = [f"# Benchmark report ({'quick' if data['quick'] else 'full'})", ""]
    m = data["machine"]
    lines += [
        f"Machine: {m['cpu']}, {m['cores']} cores, load average at start "
        f"{m['load_avg_1_5_15'][0]:.1f} / {m['load_avg_1_5_15'][1]:.1f} / "
        f"{m['load_avg_1_5_15'][2]:.1f} (1/5/15 min; the machine is shared, so timings are "
        f"minimums of repeats and comparisons are ratios within this run). Python "
        f"{m['python']}, numpy {m['numpy']}, scipy {m['scipy']}, MuJoCo {m['mujoco']}. "
        f"Compiled kernel: {'yes' if data['kernel'] else 'no (numpy fallback)'}. "
        f"Run time {data['bench_wall_s']:.0f} s.",
        "",
    ]
    lines += _headline(data) + _trade(data) + _peers(data) + _scaling(data) + _budget(data)
    lines += _extremes(data)
    lines += ["## Plots", ""] + [f"![{f}]({f})" for f in files] + [""]
    return "\n".join(lines)


def _headline(data):
    d = data["dbar_rhs"]
    p = data["peers"]
    out = [
        "## Headline figures",
        "",
        "| figure | value | target |",
        "|---|---|---|",
        f"| D-bar rhs, compiled kernel | {_us(d.get('fast_kernel'))} | <= 20 us |",
        f"| D-bar rhs, fast numpy path | {d['fast_numpy'] * 1e6:.1f} us | (fallback) |",
        f"| D-bar rhs, reference path | {d['reference'] * 1e6:.1f} us | |",
    ]
    sc = [r for r in data.get("scaling", []) if 1000 <= r["bars"] < 1100]
    for r in sc:
        tag = "class-2 (joints)" if r["joined"] else "class-1"
        out.append(f"| {r['bars']} bars rhs, {tag} | {r['fast'] * 1e3:.3f} ms | <= 2 ms |")
    for joined in (False, True):
        e = data.get("exponents", {}).get("class-2" if joined else "class-1")
        if e is not None:
            out.append(
                f"| rhs cost exponent (>= 100 bars), {'class-2' if joined else 'class-1'}"
                f" | {e:.2f} | 1 (linear) |"
            )
    ob, mb = p.get("ours_best"), p.get("mujoco_best")
    if ob:
        out.append(
            f"| ours to node <= 1e-6 m and bar <= 1e-12 (D-bar, {p['duration_s']:g} s) "
            f"| {ob['wall_s']:.3f} s ({ob['method']} {ob['setting']:.0e}) | |"
        )
    if mb and ob:
        out.append(
            f"| MuJoCo to node <= 1e-6 m | {mb['wall_s']:.3f} s (dt {mb['dt_s']:.0e}) "
            f"= {mb['wall_s'] / ob['wall_s']:.1f} x ours | > ours |"
        )
    elif p.get("mujoco"):
        best = min(p["mujoco"], key=lambda r: r["node_error_m"])
        out.append(
            f"| MuJoCo best node error in this run | {best['node_error_m']:.1e} m at "
            f"{best['wall_s']:.2f} s (dt {best['dt_s']:.0e}): 1e-6 m not reached | |"
        )
    return out + [""]


def _trade(data):
    out = [
        "## Speed against accuracy",
        "",
        "Wall time per simulated second (fast path, compiled kernel where built; timed "
        "integration only), max node error against DOP853 at rtol 1e-13, max relative "
        "bar-length error, max joint error, relative energy drift (free, unactuated scenes "
        "only) and momentum drift. Setting: dt (s) for rk4*, rtol for the adaptive methods "
        "(atol = 1e-3 rtol).",
        "",
        "### Recommended settings",
        "",
        "| case | accuracy class | integrator | setting | wall s / sim s | node error m |",
        "|---|---|---|---|---|---|",
    ]
    for rec in data["recommend"]:
        r = rec["row"]
        if r is None:
            out.append(f"| {rec['case']} | {rec['class_m']:.0e} m | none in the grid | | | |")
        else:
            out.append(
                f"| {rec['case']} | {rec['class_m']:.0e} m | {r['method']} | "
                f"{r['setting']:.0e} | {r['wall_per_sim_s']:.3g} | "
                f"{r['node_error_m']:.1e} |"
            )
    out += [
        "",
        "### All runs",
        "",
        "| case | variant | integrator | setting | s / sim s | rhs calls | node m | bar | "
        "joint m | energy | momentum |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in data["trade"]:
        if r["failure"]:
            out.append(
                f"| {r['case']} | {r['variant']} | {r['method']} | {r['setting']:.0e} | "
                f"{r['wall_per_sim_s']:.3g} | {r['nfev']} | failed: {r['failure']} "
                "| | | | |"
            )
            continue
        out.append(
            f"| {r['case']} | {r['variant']} | {r['method']} | {r['setting']:.0e} | "
            f"{r['wall_per_sim_s']:.3g} | {r['nfev']} | {r['node_error_m']:.1e} | "
            f"{r['bar_length_error']:.1e} | {r['joint_error_m']:.1e} | "
            f"{_f(r['energy_drift'], '.1e')} | {r['momentum_drift']:.1e} |"
        )
    return out + [""]


def _peers(data):
    p = data["peers"]
    out = [
        "## Peers: MuJoCo and the authors' MATLAB code",
        "",
        f"D-bar maneuver over {p['duration_s']:g} s without string damping (MuJoCo's "
        "tendon damping acts also while a string is slack, ours and MOTES' do not; with "
        "damping the two models differ by about 1e-3 m, a modelling difference, not an "
        "error). MuJoCo: bodies, ball joints, an equality `connect` loop closure, spatial "
        "tendons with a [0, rest] dead band (tension only), RK4. Node error against our "
        "DOP853 rtol 1e-13 reference; loop gap = closure distance at n1.",
        "",
        "| simulator | setting | wall s | node error m | bar / loop gap | us per step |",
        "|---|---|---|---|---|---|",
    ]
    for r in p["ours"]:
        out.append(
            f"| ours | {r['method']} {r['setting']:.0e} | {r['wall_s']:.3f} | "
            f"{r['node_error_m']:.1e} | bar {r['bar_length_error']:.1e} | |"
        )
    for r in p["mujoco"]:
        out.append(
            f"| MuJoCo | dt {r['dt_s']:.0e}, solref {r['solref_s']:.0e}, solimp "
            f"{r['solimp']} | {r['wall_s']:.3f} | {r['node_error_m']:.1e} | "
            f"gap {r['gap_m']:.1e} m | {r['us_per_step']:.1f} |"
        )
    if not p["mujoco_available"]:
        out.append("| MuJoCo | not installed (`pip install -e .[bench]`) | | | | |")
    ob, mb = p.get("ours_best"), p.get("mujoco_best")
    out.append("")
    if ob and mb:
        out.append(
            f"To node error <= 1e-6 m: MuJoCo {mb['wall_s']:.3f} s, ours "
            f"{ob['wall_s']:.3f} s (bar-length error {ob['bar_length_error']:.0e}): "
            f"MuJoCo / ours = {mb['wall_s'] / ob['wall_s']:.1f}."
        )
    elif ob:
        out.append(
            f"Ours reaches node error <= 1e-6 m and bar error <= 1e-12 in "
            f"{ob['wall_s']:.3f} s; no MuJoCo setting of this run reached 1e-6 m."
        )
    mat = p["matlab_ms_per_step"]
    out += [
        "",
        "The authors' MATLAB library (MOTES, GNU Octave 7.3, from the field notes, not "
        "rerun): "
        + ", ".join(f"{k}: {v} ms per RK4 step" for k, v in mat.items())
        + f"; our D-bar RK4 step: {data['dbar_rhs']['rk4_step'] * 1e6:.1f} us "
        f"({mat['D-bar (4 bars, gyro)'] * 1e-3 / data['dbar_rhs']['rk4_step']:.0f} x "
        "fewer).",
        "",
    ]
    return out


def _scaling(data):
    if not data.get("scaling"):
        return []
    out = [
        "## Scaling",
        "",
        "Prism chains (3 bars per prism, wheels on every bar): class 1 (hexagon strings "
        "between prisms) and class 2 (prisms standing on each other's nodes: one joint per "
        "shared node). Cost of one right-hand side and one RK4 step.",
        "",
        "| bars | class | coordinates | reference rhs us | fast numpy us | kernel us | "
        "RK4 step us |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in data["scaling"]:
        out.append(
            f"| {r['bars']} | {'2' if r['joined'] else '1'} | {r['coordinates']} | "
            f"{r['reference'] * 1e6:.1f} | {r['fast_numpy'] * 1e6:.1f} | "
            f"{_f(r.get('fast_kernel') and r['fast_kernel'] * 1e6, '.1f')} | "
            f"{r['rk4_step'] * 1e6:.1f} |"
        )
    ex = data.get("exponents", {})
    out += [
        "",
        "Fitted exponent of the fast rhs cost over the sizes >= 100 bars (all on the sparse path): "
        + ", ".join(f"{k}: {_f(v, '.2f')}" for k, v in ex.items())
        + ".",
        "",
    ]
    return out


def _budget(data):
    b = data["ekf"]
    out = [
        "## Estimator budget (D-bar, per IMU sample of 10 ms)",
        "",
        "One process step = one RK4 step over 10 ms (4 derivative calls; the estimator's lean "
        "model takes as many as its accuracy needs, two on the D-bar); "
        "Jacobian = one batched complex-step call over all dynamic states.",
        "",
        "| dynamics | process step us | Jacobian us | states |",
        "|---|---|---|---|",
    ]
    for name, r in b.items():
        out.append(
            f"| {name} | {r['process_step_s'] * 1e6:.1f} | {r['jacobian_s'] * 1e6:.1f} "
            f"| {r['states']} |"
        )
    k = b["FastDynamics"].get("kernel_rk4_step_s")
    if k:
        out.append(f"\nSingle-state RK4 step with the compiled kernel: {k * 1e6:.1f} us.")
    return out + [""]


def _extremes(data):
    rows = data.get("extremes", [])
    if not rows:
        return []
    out = [
        "## Stability at the extremes",
        "",
        "Each cell runs `simulate(..., fast=True)` and compares its nodes with a tight "
        "reference of the same scene (DOP853 at rtol 1e-11 and 1e-13; node error relative to "
        "the structure's extent). holds: within the integrator's accuracy class (1e-6 for "
        "dop853, 1e-3 for the others), with max relative bar-length error, max joint error "
        "and relative momentum drift; sensitive: the two reference runs differ by more than "
        "the class (the motion amplifies round-off; no integrator settles it); inaccurate: "
        "the references agree, the cell does not (its setting is too loose there); "
        "unverified: the references did not finish; fails: the library's error (stiffness "
        "detected, singular geometry, non-finite state with time and member); budget: "
        "wall-time budget spent before the end (slow, not broken).",
        "",
        "| group | cell | integrator | status | node | bar | joint m | momentum | wall s "
        "| message |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        msg = r.get("message", "").replace("|", "/")
        out.append(
            f"| {r['group']} | {r['cell']} | {r['integrator']} | {r['status']} | "
            f"{_f(r.get('node_error'), '.1e')} | "
            f"{_f(r.get('bar_length_error'), '.1e')} | {_f(r.get('joint_error_m'), '.1e')} "
            f"| {_f(r.get('momentum_drift'), '.1e')} | {r['wall_s']:.2f} | {msg} |"
        )
    counts = ", ".join(
        f"{label} {sum(r['status'] == status for r in rows)}"
        for status, label in (
            ("holds", "holds"),
            ("sensitive", "sensitive"),
            ("inaccurate", "inaccurate"),
            ("unverified", "unverified"),
            ("fails", "fails with a clear error"),
            ("budget", "budget"),
            ("NaN", "NaN in the output"),
        )
    )
    return out + ["", f"Cells: {len(rows)}; {counts}.", ""]
