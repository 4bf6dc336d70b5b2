"""Peers in the same run: MuJoCo on the D-bar scene, and the authors' MATLAB figure (quoted).

The D-bar as MuJoCo bodies: bar ``b12`` floats (free joint); ``b23``, ``b34``, ``b41`` hang on
it through ball joints at n2, n3, n4; an equality ``connect`` closes the loop at n1. Every bar
body carries its mass with the transverse inertia ``m_b l^2 / 12`` and a small axial inertia;
its wheel is a child body on a hinge along the bar (mass ``m_w``, inertia ``J_1``, ``J_1``,
``J_3``) spinning at the scene's initial spin. Strings are spatial tendons between node sites
with a dead band ``[0, rest]`` (tension only, as in our model); their damping acts always
(MuJoCo has no slack switch). Rest lengths follow the scene's schedules at every step.
"""

import time

import numpy as np

from gyrotensegrity import Model
from gyrotensegrity.fast import InputTable

MATLAB_MS_PER_STEP = {"double pendulum": 4.4, "D-bar (4 bars, gyro)": 6.0}  # field notes sec. 1
AXIAL_INERTIA = 1e-6  # kg m^2, bar axial inertia (the model's bars have none; torque free)


def available() -> bool:
    try:
        import mujoco  # noqa: F401
    except ImportError:
        return False
    return True


def _vec(v):
    return " ".join(f"{a:.17g}" for a in v)


def _inertia(transverse, axial, d):
    """fullinertia (xx yy zz xy xz yz) of an axisymmetric body with unit axis d."""
    inertia = transverse * (np.eye(3) - np.outer(d, d)) + axial * np.outer(d, d)
    return _vec(
        [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    )


def dbar_mjcf(model: Model, dt: float, solref_s: float, solimp: float = 0.95) -> str:
    """MJCF of a four-bar loop scene (the D-bar). Bars must form the cycle of the scene order."""
    sc = model.scene
    pos = {name: sc.positions[:, i] for i, name in enumerate(sc.node_names)}
    bodies, close = "", ""
    parent = np.zeros(3)
    for i, bar in enumerate(sc.bars):
        start, end = pos[bar.start], pos[bar.end]
        b = end - start
        length = np.linalg.norm(b)
        d = b / length
        joint = "<freejoint/>" if i == 0 else '<joint type="ball"/>'
        wheel = ""
        if bar.wheel is not None:
            w = bar.wheel
            J1 = w.mass * (3 * w.radius**2 + w.thickness**2) / 12.0
            J3 = 0.5 * w.mass * w.radius**2
            wheel = (
                f'<body name="w{i}" pos="{_vec(b / 2)}">'
                f'<joint name="spin{i}" type="hinge" axis="{_vec(d)}"/>'
                f'<inertial pos="0 0 0" mass="{w.mass}" fullinertia="{_inertia(J1, J3, d)}"/>'
                "</body>"
            )
        inertia = _inertia(bar.mass * length**2 / 12.0, AXIAL_INERTIA, d)
        bodies += (
            f'<body name="bar{i}" pos="{_vec(start - parent)}">{joint}'
            f'<inertial pos="{_vec(b / 2)}" mass="{bar.mass}" fullinertia="{inertia}"/>'
            f'<site name="{bar.start}" pos="0 0 0"/>{wheel}'
        )
        parent = start
        if i == len(sc.bars) - 1:
            bodies += f'<site name="close" pos="{_vec(b)}"/>'
            close = (
                f'<connect body1="bar{i}" body2="bar0" anchor="{_vec(b)}" solref="{solref_s} 1" '
                f'solimp="{solimp} {solimp} 0.001"/>'
            )
    bodies += "</body>" * len(sc.bars)
    tendons = "".join(
        f'<spatial name="{s.name}" stiffness="{s.stiffness}" damping="{s.damping}" '
        f'springlength="0 {s.rest_length(0.0)}"><site site="{s.start}"/><site site="{s.end}"/>'
        "</spatial>"
        for s in sc.strings
    )
    return (
        '<mujoco model="dbar"><compiler angle="radian"/>'
        f'<option timestep="{dt}" integrator="RK4" gravity="{_vec(sc.gravity)}">'
        '<flag contact="disable" refsafe="disable"/></option>'
        f"<worldbody>{bodies}</worldbody><equality>{close}</equality>"
        f"<tendon>{tendons}</tendon></mujoco>"
    )


def run_mujoco(model: Model, dt, solref_s, duration, sample_dt, solimp=0.95):
    """Run the D-bar in MuJoCo; nodes sampled every ``sample_dt``.

    Returns
    -------
    dict
        ``t`` (K,), ``N`` (K, 3, 4) primary nodes n1..n4 in scene order, ``gap_m`` (max
        loop-closure gap), ``wall_s`` (stepping only, with the rest-length updates).
    """
    import mujoco

    m = mujoco.MjModel.from_xml_string(dbar_mjcf(model, dt, solref_s, solimp))
    d = mujoco.MjData(m)
    sc = model.scene
    for i, bar in enumerate(sc.bars):
        if bar.wheel is not None:
            d.qvel[m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"spin{i}")]] = (
                bar.wheel.spin0
            )
    mujoco.mj_forward(m, d)
    sites = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, name) for name in sc.node_names]
    close = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "close")
    first = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, sc.bars[0].start)
    inputs, alpha = InputTable(model), model.alpha  # same schedule lookup as ours
    steps = max(1, int(round(sample_dt / dt)))
    n_samples = int(round(duration / sample_dt))
    out, gap = [d.site_xpos[sites].T.copy()], 0.0
    spring = m.tendon_lengthspring
    wall = 0.0
    for _ in range(n_samples):
        start = time.perf_counter()
        for _ in range(steps):
            spring[:, 1] = inputs(d.time)[:alpha]
            mujoco.mj_step(m, d)
        wall += time.perf_counter() - start
        out.append(d.site_xpos[sites].T.copy())
        gap = max(gap, float(np.linalg.norm(d.site_xpos[close] - d.site_xpos[first])))
        if not np.all(np.isfinite(d.qpos)):
            break
    t = np.arange(len(out)) * steps * dt
    return {"t": t, "N": np.array(out), "gap_m": gap, "wall_s": wall, "steps": n_samples * steps}


OURS = (
    ("dop853", 1e-9),
    ("dop853", 1e-10),
    ("dop853", 1e-11),
    ("rk4", 1e-4),
    ("rk4-projected", 2e-4),
)
MUJOCO_FULL = (
    (1e-4, 0.02, 0.9),
    (1e-4, 5e-4, 0.95),
    (1e-4, 2e-4, 0.9999),
    (5e-5, 1e-4, 0.9999),
    (2e-5, 4e-5, 0.9999),
    (1e-5, 2e-5, 0.9999),
)
MUJOCO_QUICK = ((1e-4, 2e-4, 0.9999),)
TARGET_NODE_M, TARGET_BAR = 1e-6, 1e-12


def compare(quick: bool, log=print) -> dict:
    """Ours and MuJoCo on the D-bar maneuver without string damping (MuJoCo's tendon damping
    cannot switch off while a string is slack), errors against our tight reference."""
    from .runner import Variant, errors, integrate
    from .trade import REFERENCE, dbar_model

    duration = 0.5 if quick else 3.0
    model = dbar_model(damping=0.0)
    variant = Variant("D-bar, no string damping", model)
    ref = integrate(variant, *REFERENCE, duration, 0.01)
    ours = []
    for method, setting in OURS[1:2] if quick else OURS:
        run = integrate(variant, method, setting, duration, 0.01)
        row = {
            "method": method,
            "setting": setting,
            "wall_s": run.wall_s,
            "failure": run.failure,
        } | errors(variant, run, ref)
        ours.append(row)
        log(
            f"  ours   {method:13s} {setting:8.0e}: {run.wall_s:7.3f} s, "
            f"node {row['node_error_m']:.1e} m, bar {row['bar_length_error']:.1e}"
        )
    primary = [model.structure.primary[n] for n in model.scene.node_names]
    peers = []
    if available():
        for dt, solref, solimp in MUJOCO_QUICK if quick else MUJOCO_FULL:
            r = run_mujoco(model, dt, solref, duration, 0.01, solimp)
            k = len(r["t"])
            err = float(np.max(np.abs(r["N"] - ref.N[:k][:, :, primary])))
            peers.append(
                {
                    "dt_s": dt,
                    "solref_s": solref,
                    "solimp": solimp,
                    "wall_s": r["wall_s"],
                    "us_per_step": r["wall_s"] / r["steps"] * 1e6,
                    "node_error_m": err,
                    "gap_m": r["gap_m"],
                    "complete": k == int(round(duration / 0.01)) + 1,
                }
            )
            log(
                f"  MuJoCo dt {dt:.0e} solref {solref:.0e} solimp {solimp}: {r['wall_s']:7.3f} s "
                f"node {err:.1e} m, loop gap {r['gap_m']:.1e} m"
            )
    ok = [
        r
        for r in ours
        if r["node_error_m"] <= TARGET_NODE_M and r["bar_length_error"] <= TARGET_BAR
    ]
    mj_ok = [r for r in peers if r["node_error_m"] <= TARGET_NODE_M and r["complete"]]
    best = min(ok, key=lambda r: r["wall_s"]) if ok else None
    mj_best = min(mj_ok, key=lambda r: r["wall_s"]) if mj_ok else None
    return {
        "duration_s": duration,
        "ours": ours,
        "mujoco": peers,
        "ours_best": best,
        "mujoco_best": mj_best,
        "mujoco_available": available(),
        "matlab_ms_per_step": MATLAB_MS_PER_STEP,
    }
