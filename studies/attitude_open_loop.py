"""``python -m studies.attitude_open_loop``: three-axis attitude plans played open loop on the
full model: the landing error the plan predicts against the one the simulation gives.

Cases:

- ``prism``: prism-rig with strings 100 times stiffer (the quasi-static shape holds; the
  shipped prism's 10 N/m strings ring at about 1 Hz, sqrt(k / m) on 0.16 kg bars, too near a
  shape change of a second or two for the shape to sit at its equilibrium),
  wheels at +-150 rad/s held (they give the momentum the strings steer), strings s7 and s8
  actuated; the target a turn about the total momentum (rolling, pitching and yawing at once).
  With the wheels held and the strings back at rest, the body lands (stops turning) only where
  it sees the momentum as at the start: after a turn about the momentum
  (docs/attitude-plans.md).
- ``prism-wheels``: the same prism, strings s7 and s8 and the three wheels planned together, a
  target off the momentum and off every body axis. The prism's bars meet only strings, so in
  the paper's model a wheel's motor reaction leaves the structure (control/wheel_reaction.py):
  a wheel turns the prism only through its gyroscopic couple while the shape moves its axis,
  and a net turn needs its spin to change while the shape is away from rest. Each planned
  wheel acceleration becomes the motor torque ``J_3 omega_w_dot``.
- ``dbar``: planned on dbar-gyro (strings and wheels), played on dbar-rig, the rig-fidelity
  truth (hinges, stators, the motors' reaction): each planned wheel acceleration becomes the
  motor torque ``J_3 omega_w_dot``, n1-n3 and n2-n4 follow the plan (dbar-rig has no n2-n4
  string: the hinges keep its rhombus planar, but with n1-n3 at zero tension nothing keeps it
  from folding in its plane under the wheels' reactions; dbar-gyro's follower string is added,
  as the planner's model assumes). A target the D-bar can land at: its wheels' momenta lie in
  its plane, so it only stops turning at attitudes whose plane normal stays perpendicular to
  the total momentum (here along the start's y).

Prints per case: the target, the plan's predicted landing error and body rate, plan time, the
simulated landing error (geodesic, the body frame's attitude at the landing) and its drift
over ``--settle`` seconds after it.
"""

import argparse
import math
import time

import numpy as np
from scipy.spatial.transform import Rotation

from gyrohost.control.attitude_planner import AttitudeWeights, plan_attitude, target_quaternion
from gyrohost.control.schedule import Limits
from gyrohost.control.shape_attitude import AttitudeModel
from gyrohost.resources import shipped
from gyrotensegrity import BodyFrame, Model, load_scene, scene_from_dict
from gyrotensegrity.attitude import angle_between, euler_zyx
from gyrotensegrity.compat import tomllib
from gyrotensegrity.simulate import Stepper

DBAR_TARGET_DEG = (10.0, -20.0, -27.27)
"""Roll 10, pitch -20 and the yaw that keeps the plane's normal perpendicular to y:
``tan(yaw) = tan(roll) / sin(pitch)``."""


PRISM_TARGET_DEG = (2.0, -2.0, 3.0)
"""A turn of 4.2 deg about an axis off every body axis and off the momentum."""
PRISM_OPTIONS = dict(weights=AttitudeWeights(1e-6, 1e-6), landing_rate_rad_s=1e-4)
"""Planner options for the prism with wheels: effort weights far below the landing term's (a
turn of 4 deg is 5e-3 rad^2; the default 1e-4 on inputs near their limits weighs as much as a
landing 0.6 deg off, sqrt(1e-4) rad) and a landing rate of 0.006 deg/s (a drift of 0.006 deg in
the settle second)."""


def parse(argv):
    p = argparse.ArgumentParser(prog="python -m studies.attitude_open_loop", description=__doc__)
    p.add_argument("--case", choices=("prism", "prism-wheels", "dbar", "all"), default="all")
    p.add_argument("--prism-turn", type=float, default=1.5, help="about the momentum, deg")
    p.add_argument("--duration", type=float, default=6.0, help="maneuver length, s")
    p.add_argument("--settle", type=float, default=1.0, help="time after the landing, s")
    return p.parse_args(argv)


def stiff_prism_data():
    """prism-rig's scene table, strings 100 times stiffer, wheels at +-150 rad/s."""
    data = tomllib.loads(shipped("scene", "prism-rig").read_text())
    for string in data["strings"]:
        string["stiffness"] *= 100.0
    for bar, spin in zip(data["bars"], (150.0, -150.0, 150.0), strict=True):
        bar["wheel"]["spin"] = spin
    return data


def stiff_prism():
    return Model(scene_from_dict(stiff_prism_data(), "prism-stiff.toml"))


def dbar_truth(plan, planner_model, a=1):
    """dbar-rig with the plan's n1-n3 rest lengths, dbar-gyro's n2-n4 string on the plan's
    follower lengths, and the plan's wheel accelerations as motor torques."""
    data = tomllib.loads(shipped("scene", "dbar-rig").read_text())
    s = plan.schedule
    data["strings"][0]["rest_length"] = {"t": s.t.tolist(), "value": s.rest_length[:, 0].tolist()}
    follower = dict(data["strings"][0], name="s24", nodes=["n2", "n4"])
    follower["rest_length"] = {"t": s.t.tolist(), "value": s.rest_length[:, 1].tolist()}
    data["strings"].append(follower)
    set_wheel_torques(data, plan, planner_model, a)
    data["scene"]["duration"] = float(plan.knot_t_s[-1]) + 2.0
    return Model(scene_from_dict(data, "dbar-rig-planned.toml"))


def set_wheel_torques(data, plan, planner_model, a):
    """Each bar's wheel driven by the motor torque ``J_3 omega_w_dot`` of the plan's wheel
    accelerations (inputs ``a`` on; piecewise constant, 0.1 ms edges as the shipped scenes')."""
    kt = plan.knot_t_s
    for k, bar in enumerate(b for b in data["bars"] if "wheel" in b):
        J3 = planner_model.J3[planner_model.wheel_bars[k]]
        torque = J3 * plan.inputs[:, a + k]
        t, v = [0.0], [float(torque[0])]
        for j in range(1, len(torque)):
            t += [float(kt[j]), float(kt[j]) + 1e-4]
            v += [float(torque[j - 1]), float(torque[j])]
        t += [float(kt[-1]), float(kt[-1]) + 1e-4]
        v += [float(torque[-1]), 0.0]
        bar["wheel"]["torque"] = {"t": t, "value": v}


def play(model, schedule, duration_s, settle_s, fast, dt=1e-3, max_dt=2e-5):
    """Body-frame quaternions at the landing and ``settle_s`` after it, by stepping the full
    model with the schedule's rest lengths (its scene's own inputs otherwise)."""
    stepper = Stepper(model, max_dt=max_dt, fast=fast)
    frame, out, t = BodyFrame.of_model(model), [], 0.0
    for end in (duration_s, duration_s + settle_s):
        while t < end - 1e-12:
            h = min(dt, end - t)
            u = model.input_at(t + 0.5 * h)
            if schedule is not None:
                u[schedule.bind(model)] = schedule(t + 0.5 * h)
            x = stepper.step(h, u)
            t += h
        out.append(frame.attitude(model.nodes(x)[0]).quaternion)
    return out


def report(name, target_deg, plan, q_land, q_after, settle_s, plan_s, sim_s):
    q_target = target_quaternion(np.radians(target_deg))
    print(f"{name}: target roll, pitch, yaw {', '.join(f'{v:+.2f}' for v in target_deg)} deg")
    print(
        f"  plan      {math.degrees(plan.landing_error_rad):.4f} deg off, body rate "
        f"{math.degrees(plan.landing_rate_rad_s):.4f} deg/s, {plan_s:.2f} s to plan "
        f"({plan.n_eval} evaluations, {plan.message})"
    )
    print(
        f"  full model {math.degrees(angle_between(q_target, q_land)):.4f} deg off at the "
        f"landing, drifts {math.degrees(angle_between(q_land, q_after)):.4f} deg in "
        f"{settle_s:g} s after it ({sim_s:.1f} s to simulate)"
    )


def momentum_turn_deg(model, turn_deg):
    """Roll, pitch, yaw (deg) of a turn by ``turn_deg`` about the prism's momentum: the turn its
    strings s7 and s8 alone make (the wheels held)."""
    _, H0 = AttitudeModel(model, ["s7", "s8"]).start(model.initial_state())
    turn = Rotation.from_rotvec(np.radians(turn_deg) * H0 / np.linalg.norm(H0))
    return np.degrees(euler_zyx(turn.as_matrix()))


def prism_case(a):
    model = stiff_prism()
    target = momentum_turn_deg(model, a.prism_turn)
    start = time.perf_counter()
    plan = plan_attitude(model, np.radians(target), a.duration, strings=["s7", "s8"],
                         mode="strings")  # fmt: skip
    plan_s = time.perf_counter() - start
    start = time.perf_counter()
    q_land, q_after = play(model, plan.schedule, a.duration, a.settle, fast=True)
    report("prism", target, plan, q_land, q_after, a.settle, plan_s, time.perf_counter() - start)


def prism_wheels_case(a):
    data = stiff_prism_data()
    model = Model(scene_from_dict(data, "prism-stiff.toml"))
    start = time.perf_counter()
    plan = plan_attitude(model, np.radians(PRISM_TARGET_DEG), a.duration, strings=["s7", "s8"],
                         **PRISM_OPTIONS)  # fmt: skip
    plan_s = time.perf_counter() - start
    set_wheel_torques(data, plan, model, 2)
    truth = Model(scene_from_dict(data, "prism-stiff-planned.toml"))
    start = time.perf_counter()
    q_land, q_after = play(truth, plan.schedule, a.duration, a.settle, fast=True)
    sim_s = time.perf_counter() - start
    report("prism-wheels", PRISM_TARGET_DEG, plan, q_land, q_after, a.settle, plan_s, sim_s)
    peak = np.max(np.abs(plan.schedule.wheel_speed), axis=0)
    travel = np.ptp(plan.schedule.rest_length, axis=0)
    print(f"  peak wheel speeds {', '.join(f'{v:.1f}' for v in peak)} rad/s, string travel "
          f"{', '.join(f'{1e3 * v:.1f}' for v in travel)} mm")  # fmt: skip


def dbar_case(a):
    model = Model(load_scene(shipped("scene", "dbar-gyro")))
    start = time.perf_counter()
    plan = plan_attitude(model, np.radians(DBAR_TARGET_DEG), a.duration, Limits())
    plan_s = time.perf_counter() - start
    truth = dbar_truth(plan, model)
    start = time.perf_counter()
    q_land, q_after = play(truth, None, a.duration, a.settle, fast=False, max_dt=5e-4)
    sim_s = time.perf_counter() - start
    report("dbar", DBAR_TARGET_DEG, plan, q_land, q_after, a.settle, plan_s, sim_s)


def main(argv=None) -> int:
    a = parse(argv)
    if a.case in ("prism", "all"):
        prism_case(a)
    if a.case in ("prism-wheels", "all"):
        prism_wheels_case(a)
    if a.case in ("dbar", "all"):
        dbar_case(a)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
