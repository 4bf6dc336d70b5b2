"""The rig-fidelity model against MuJoCo modelling the same rig independently.

MuJoCo's D-bar: bar b12 floats (free joint); b23, b34, b41 hang on it through hinge joints at
n2, n3, n4 (axis normal to the rhombus), an equality ``connect`` closes the loop at n1 (the
hinge axis there follows from the other three). Each bar body carries its mass with the
transverse inertia ``m_b l^2 / 12`` and the stator's axial inertia; its rotor is a child body on
a hinge along the bar (mass ``m_w``, inertia ``J_1, J_1, J_3``) driven by a ``motor`` actuator,
so the motor torque acts on the rotor and, reversed, on the bar. Strings are spatial tendons
with a dead band ``[0, rest]`` (tension only) and no damping (MuJoCo's tendon damping also acts
while slack). RK4 at dt 5e-5 s with a stiff loop closure (time constant 2 dt, solimp 0.9999);
inputs are held over each step at their value in its middle.
"""

import dataclasses
from importlib.resources import files

import mujoco
import numpy as np
import pytest
from test_rig_fidelity import dbar_rig_scene

from gyrotensegrity import Model, load_scene, simulate

DT_S, SOLREF_S, SOLIMP = 5e-5, 1e-4, 0.9999
SAMPLE_DT_S = 0.01
NODE_TOLERANCE_M = 1e-6
FRAME_MASS_KG = 1e-5  # the frame's mass; the difference to the hinge model grows with it


def _vec(v):
    return " ".join(f"{a:.17g}" for a in v)


def _inertia(transverse, axial, d):
    """MJCF fullinertia (xx yy zz xy xz yz) of a body symmetric about the unit axis d."""
    inertia = transverse * (np.eye(3) - np.outer(d, d)) + axial * np.outer(d, d)
    return _vec([inertia[i, j] for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))])


def _bar(i, bar, b, stator, attributes, joint, site=""):
    """Bar body i, left open (its joint, inertia and site), with its rotor on a hinge along it."""
    length = np.linalg.norm(b)
    d = b / length
    w = bar.wheel
    J1 = w.mass * (3 * w.radius**2 + w.thickness**2) / 12.0
    J3 = 0.5 * w.mass * w.radius**2
    return (
        f'<body name="bar{i}" {attributes}>{joint}'
        f'<inertial pos="{_vec(b / 2)}" mass="{bar.mass}" '
        f'fullinertia="{_inertia(bar.mass * length**2 / 12.0, stator, d)}"/>{site}'
        f'<body name="rotor{i}" pos="{_vec(b / 2)}">'
        f'<joint name="spin{i}" type="hinge" axis="{_vec(d)}"/>'
        f'<inertial pos="0 0 0" mass="{w.mass}" fullinertia="{_inertia(J1, J3, d)}"/>'
        "</body>"
    )


def _connect(body1, body2, anchor):
    return (
        f'<connect body1="{body1}" body2="{body2}" anchor="{_vec(anchor)}" '
        f'solref="{SOLREF_S} 1" solimp="{SOLIMP} {SOLIMP} 0.001"/>'
    )


def _document(name, sc, worldbody, equality, strings):
    """The MJCF around the bodies: RK4, no contacts, tension-only tendons, one motor per rotor."""
    tendons = "".join(
        f'<spatial name="{s.name}" stiffness="{s.stiffness}" '
        f'springlength="0 {s.rest_length(0.0)}"><site site="{s.start}"/><site site="{s.end}"/>'
        "</spatial>"
        for s in strings
    )
    actuators = "".join(f'<motor joint="spin{i}" gear="1"/>' for i in range(len(sc.bars)))
    return (
        f'<mujoco model="{name}"><compiler angle="radian"/>'
        f'<option timestep="{DT_S}" integrator="RK4" gravity="{_vec(sc.gravity)}">'
        '<flag contact="disable"/></option>'
        f"<worldbody>{worldbody}</worldbody><equality>{equality}</equality>"
        f"<tendon>{tendons}</tendon><actuator>{actuators}</actuator></mujoco>"
    )


def rig_mjcf(model: Model) -> str:
    """MJCF of a four-bar loop scene whose bars form the cycle of the scene order."""
    sc = model.scene
    pos = {name: sc.positions[:, i] for i, name in enumerate(sc.node_names)}
    bodies, parent = "", np.zeros(3)
    bars = [(pos[b.start], pos[b.end], b) for b in sc.bars]
    for i, (start, end, bar) in enumerate(bars):
        b = end - start
        if i == 0:
            joint = "<freejoint/>"
        else:
            prev = bars[i - 1][1] - bars[i - 1][0]
            axis = np.cross(prev, b)
            joint = f'<joint type="hinge" axis="{_vec(axis / np.linalg.norm(axis))}"/>'
        site = f'<site name="{bar.start}" pos="0 0 0"/>'
        bodies += _bar(
            i, bar, b, sc.rig.stator_inertia, f'pos="{_vec(start - parent)}"', joint, site
        )
        parent = start
    bodies += "</body>" * len(bars)
    close = _connect(f"bar{len(bars) - 1}", "bar0", bars[-1][1] - bars[-1][0])
    return _document("dbar-rig", sc, bodies, close, sc.strings)


def frame_mjcf(model: Model, frame_mass_kg: float) -> str:
    """MJCF of the rig's cross frame: a free body at the rhombus centre with two lines (n1-n3,
    n2-n4); each node is a slider on its line, each bar hangs on the slider of its start node
    by a hinge normal to the frame and is closed on the slider of its end node. The frame holds
    the rhombus, so the scene's string s24 is left out."""
    sc = model.scene
    pos = {name: sc.positions[:, i] for i, name in enumerate(sc.node_names)}
    centre = np.mean(list(pos.values()), axis=0)
    normal = np.cross(pos["n3"] - pos["n1"], pos["n2"] - pos["n4"])
    hinge = f'<joint type="hinge" axis="{_vec(normal / np.linalg.norm(normal))}"/>'
    f, tiny = frame_mass_kg, frame_mass_kg * 1e-3
    sliders, closes = "", ""
    for i, bar in enumerate(sc.bars):
        start, end = pos[bar.start], pos[bar.end]
        line = (start - centre) / np.linalg.norm(start - centre)
        sliders += (
            f'<body name="slider_{bar.start}" pos="{_vec(start - centre)}">'
            f'<joint type="slide" axis="{_vec(line)}"/>'
            f'<inertial pos="0 0 0" mass="{tiny}" diaginertia="{tiny} {tiny} {tiny}"/>'
            f'<site name="{bar.start}" pos="0 0 0"/>'
            + _bar(i, bar, end - start, sc.rig.stator_inertia, "", hinge)
            + "</body></body>"
        )
        closes += _connect(f"bar{i}", f"slider_{bar.end}", end - start)
    frame = (
        f'<body name="frame" pos="{_vec(centre)}"><freejoint/>'
        f'<inertial pos="0 0 0" mass="{f}" diaginertia="{f * 1e-2} {f * 1e-2} {f * 1e-2}"/>'
        f"{sliders}</body>"
    )
    strings = [s for s in sc.strings if s.name != "s24"]
    return _document("dbar-frame", sc, frame, closes, strings)


def run_mujoco(model: Model, duration_s: float, xml: str | None = None):
    """Primary nodes (K, 3, n_scene) every SAMPLE_DT_S; rest lengths and motor torques follow
    the scene's schedules (taken at the middle of each step). ``xml`` default: rig_mjcf."""
    m = mujoco.MjModel.from_xml_string(xml or rig_mjcf(model))
    d = mujoco.MjData(m)
    sc = model.scene
    for i, bar in enumerate(sc.bars):
        joint = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"spin{i}")
        d.qvel[m.jnt_dofadr[joint]] = bar.wheel.spin0
    mujoco.mj_forward(m, d)
    sites = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, n) for n in sc.node_names]
    names = [s.name for s in sc.strings]
    tendons = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_TENDON, k) for k in range(m.ntendon)]
    rest = [sc.strings[names.index(name)].rest_length for name in tendons]
    motor = [bar.wheel.torque for bar in sc.bars]
    steps = int(round(SAMPLE_DT_S / DT_S))
    n_samples = int(round(duration_s / SAMPLE_DT_S))
    middle = (np.arange(n_samples * steps) + 0.5) * DT_S  # the input over each step
    springs, torques = (
        np.array([np.interp(middle, q.t, q.value) for q in schedules]).T.reshape(
            n_samples, steps, -1
        )
        for schedules in (rest, motor)
    )
    out = [d.site_xpos[sites].T.copy()]
    for k in range(n_samples):
        for j in range(steps):
            m.tendon_lengthspring[:, 1] = springs[k, j]
            d.ctrl[:] = torques[k, j]
            mujoco.mj_step(m, d)
        out.append(d.site_xpos[sites].T.copy())
    return np.array(out)


def node_error(model: Model, duration_s: float):
    """Max over samples and primary nodes of |ours - MuJoCo|, and MuJoCo's largest node
    displacement, both m."""
    ours = simulate(model, duration=duration_s, rtol=1e-11, atol=1e-13, sample_dt=SAMPLE_DT_S)
    primary = [model.structure.primary[n] for n in model.scene.node_names]
    peer = run_mujoco(model, duration_s)
    moved = float(np.max(np.abs(peer - peer[0])))
    return float(np.max(np.abs(ours["N"][:, :, primary] - peer))), moved


@pytest.mark.parametrize("case", ["spin-up", "braking"])
def test_spin_up_and_braking_at_rest_match_mujoco(case):
    model = Model(dbar_rig_scene(case, damping=0.0))
    err, moved = node_error(model, 0.2)
    print(f"{case}: node error against MuJoCo {err:.2e} m (nodes moved {moved:.2e} m)")
    assert moved > 1e-3  # the structure turned
    assert err < NODE_TOLERANCE_M


def test_dbar_maneuver_with_hinges_matches_mujoco():
    model = Model(dbar_rig_scene("maneuver", damping=0.0))
    err, moved = node_error(model, 0.3)
    print(f"maneuver with hinges: node error against MuJoCo {err:.2e} m (moved {moved:.2e} m)")
    assert moved > 1e-3
    assert err < NODE_TOLERANCE_M


def test_cross_frame_adds_nothing_to_the_hinged_rhombus():
    """The rig's sliding-hinge frame (nearly massless here) against the hinge model without
    a string n2-n4: same node motion. The tracking string s24 of the ball-joint scenes, added to
    the hinge model, fights the elastic s13 (it tracks s13's rest length, not its length)."""
    model = Model(dbar_rig_scene("maneuver", damping=0.0))
    assert [s.name for s in model.scene.strings] == ["s13"]
    duration = 0.2
    peer = run_mujoco(model, duration, frame_mjcf(model, FRAME_MASS_KG))
    primary = [model.structure.primary[n] for n in model.scene.node_names]
    ours = simulate(model, duration=duration, rtol=1e-11, atol=1e-13, sample_dt=SAMPLE_DT_S)
    err = float(np.max(np.abs(ours["N"][:, :, primary] - peer)))
    gyro = load_scene(files("gyrotensegrity") / "scenes" / "dbar-gyro.toml")
    s24 = next(s for s in gyro.strings if s.name == "s24")
    tracked = Model(dataclasses.replace(model.scene, strings=[*model.scene.strings, s24]))
    with_s24 = simulate(tracked, duration=0.1, rtol=1e-8, atol=1e-10, sample_dt=SAMPLE_DT_S)
    k = len(with_s24["t"])  # a shorter run: the two strings' fight makes it costly
    err_s24 = float(np.max(np.abs(with_s24["N"][:, :, primary] - peer[:k])))
    print(f"cross frame vs hinges: {err:.1e} m; vs hinges + s24 (0.1 s): {err_s24:.1e} m")
    assert err < NODE_TOLERANCE_M
    assert err_s24 > 1e-4
