"""A :class:`gyrotensegrity.Scene` written back as a complete scene file (docs/scene-format.md),
for the identified scene: every key the loader reads, numbers in full precision (``repr``)."""

import numpy as np

from gyrotensegrity import Scene
from gyrotensegrity.piecewise import PiecewiseLinear


def _num(x) -> str:
    return repr(float(x))


def _vec(v) -> str:
    return "[" + ", ".join(_num(x) for x in np.ravel(v)) + "]"


def _str(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _schedule(s: PiecewiseLinear) -> str:
    if len(s.t) == 1:
        return _num(s.value[0])
    return f"{{ t = {_vec(s.t)}, value = {_vec(s.value)} }}"


def scene_toml(scene: Scene, header: str = "") -> str:
    """The TOML text of ``scene``; ``header`` (lines) goes first as comments."""
    out = [f"# {line}" for line in header.splitlines()]
    out += ["[scene]", f"name = {_str(scene.name)}", f"duration = {_num(scene.duration)}"]
    out += [f"gravity = {_vec(scene.gravity)}", "", "[nodes]"]
    out += [f"{n} = {_vec(scene.positions[:, i])}" for i, n in enumerate(scene.node_names)]
    moving = [i for i in range(len(scene.node_names)) if np.any(scene.velocities[:, i])]
    if moving:
        out += ["", "[velocities]"]
        out += [f"{scene.node_names[i]} = {_vec(scene.velocities[:, i])}" for i in moving]
    if scene.fixed:
        out += ["", "[constraints]", "fixed = [" + ", ".join(map(_str, scene.fixed)) + "]"]
    if scene.point_masses:
        out += ["", "[point_masses]"] + [f"{k} = {_num(v)}" for k, v in scene.point_masses.items()]
    for node, force in scene.forces.items():
        out += ["", "[[forces]]", f"node = {_str(node)}", f"force = {_vec(force)}"]
    for b in scene.bars:
        out += [
            "",
            "[[bars]]",
            f"name = {_str(b.name)}",
            f"nodes = [{_str(b.start)}, {_str(b.end)}]",
        ]
        out.append(f"mass = {_num(b.mass)}")
        if b.inertia is not None:
            out.append(f"inertia = {_num(b.inertia)}")
        w = b.wheel
        if w is not None:
            out += ["[bars.wheel]", f"mass = {_num(w.mass)}", f"radius = {_num(w.radius)}"]
            out.append(f"thickness = {_num(w.thickness)}")
            out += [f"{k} = {_num(getattr(w, k))}" for k in ("J3", "J1") if getattr(w, k)]
            if w.mode == "speed":
                out.append(f"spin = {_schedule(w.speed)}")
            else:
                out += [f"spin = {_num(w.spin0)}", f"torque = {_schedule(w.torque)}"]
    for s in scene.strings:
        out += [
            "",
            "[[strings]]",
            f"name = {_str(s.name)}",
            f"nodes = [{_str(s.start)}, {_str(s.end)}]",
        ]
        out += [f"stiffness = {_num(s.stiffness)}", f"damping = {_num(s.damping)}"]
        out.append(f"rest_length = {_schedule(s.rest_length)}")
    if scene.rig is not None:
        r = scene.rig
        out += ["", "[rig_fidelity]", f"joints = {_str(r.joints)}"]
        out += [f"stator_inertia = {_num(r.stator_inertia)}"]
        out += [f"motor_reaction = {'true' if r.motor_reaction else 'false'}"]
    if scene.attitude_frame is not None:
        out += ["", "[attitude]", "frame = [" + ", ".join(map(_str, scene.attitude_frame)) + "]"]
    sim = scene.simulation
    out += ["", "[simulation]", f"integrator = {_str(sim.integrator)}"]
    out += [f"{k} = {_num(getattr(sim, k))}" for k in ("dt", "rtol", "atol", "sample_dt")]
    out.append(f"constraint_tolerance = {_num(sim.constraint_tolerance)}")
    return "\n".join(out) + "\n"
