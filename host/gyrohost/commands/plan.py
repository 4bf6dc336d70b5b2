"""``gyrotens plan SCENE --target-attitude ROLL,PITCH,YAW [--target-shape FILE]
[--strings-only | --wheels-only] [--strings NAMES] [--duration S] [--max-speed M/S]
[--max-wheel-speed RAD/S] -o SCHEDULE``:
plan rest lengths and wheel speeds that turn a free scene to a target attitude and land it
there, on the reduced attitude model (docs/schedule.md#attitude-plans), and write the schedule.
"""

import math
from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser(
        "plan", help="plan a schedule that turns a scene to a target attitude (strings, wheels)"
    )
    p.add_argument("scene", help="scene file (TOML) or shipped name (dbar-gyro, prism-rig)")
    p.add_argument(
        "--target-attitude",
        required=True,
        metavar="ROLL,PITCH,YAW",
        help="degrees, the scene's body frame (intrinsic Z-Y-X, docs/scene-format.md)",
    )
    p.add_argument(
        "--target-shape",
        type=Path,
        metavar="FILE",
        help="TOML [rest_length] table of actuated strings to land at, m (default: the scene's)",
    )
    only = p.add_mutually_exclusive_group()
    only.add_argument("--strings-only", action="store_true", help="hold the wheels' spins")
    only.add_argument("--wheels-only", action="store_true", help="hold the rest lengths")
    p.add_argument(
        "--strings",
        metavar="NAMES",
        help="comma-separated actuated strings, at most 3 (default: those the scene schedules)",
    )
    p.add_argument("--duration", type=float, default=4.0, metavar="S", help="landing time (4 s)")
    p.add_argument(
        "--max-speed", type=float, metavar="M/S", help="servo speed (default Limits', 0.05 m/s)"
    )
    p.add_argument(
        "--max-wheel-speed",
        type=float,
        metavar="RAD/S",
        help="largest |spin| (default Limits': the wheel board's SPEED_MAX, 157.08 rad/s)",
    )
    p.add_argument("-o", "--out", type=Path, required=True, help="schedule to write (.toml/.json)")
    p.set_defaults(func=run)


def attitude_angles(text):
    """Roll, pitch, yaw (rad) of the option's ``ROLL,PITCH,YAW`` degrees."""
    from gyrohost.commands.errors import CliError

    parts = text.split(",")
    try:
        values = [float(v) for v in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise CliError(f"--target-attitude {text!r}: need three numbers ROLL,PITCH,YAW in degrees")
    return [math.radians(v) for v in values]


def _limits(args):
    from gyrohost.commands.errors import CliError
    from gyrohost.control import Limits

    given = {}
    for option, key, value in (
        ("--max-speed", "max_speed_m_s", args.max_speed),
        ("--max-wheel-speed", "max_wheel_speed_rad_s", args.max_wheel_speed),
    ):
        if value is None:
            continue
        if not (math.isfinite(value) and value > 0.0):
            raise CliError(f"{option} {value}: must be a positive number")
        given[key] = value
    return Limits(**given)


def run(args) -> int:
    from gyrohost.commands.errors import CliError
    from gyrohost.control import PlanError
    from gyrohost.control.attitude_planner import plan_attitude
    from gyrohost.control.target_shape import load_target_shape
    from gyrohost.resources import ResourceError, resolve
    from gyrotensegrity import Model, SceneError, load_scene

    target = attitude_angles(args.target_attitude)
    if args.out.suffix not in (".toml", ".json"):
        raise CliError(f"-o {args.out}: schedule files end in .toml or .json")
    strings = None if args.strings is None else [s for s in args.strings.split(",") if s]
    mode = "strings" if args.strings_only else "wheels" if args.wheels_only else "both"
    try:
        model = Model(load_scene(resolve("scene", args.scene)))
        shape = None if args.target_shape is None else load_target_shape(args.target_shape)
        plan = plan_attitude(
            model, target, args.duration, _limits(args), strings, mode, target_rest=shape
        )
    except (ResourceError, SceneError, PlanError) as exc:
        raise CliError(str(exc)) from None
    plan.schedule.save(args.out)
    _report(plan, args.out)
    return 0 if plan.success else 1


def _report(plan, out) -> None:
    from scipy.spatial.transform import Rotation

    from gyrotensegrity.attitude import euler_zyx

    s = plan.schedule
    rpy = euler_zyx(Rotation.from_quat(plan.predicted_q, scalar_first=True).as_matrix())
    print(
        f"{out}: {len(s.names)} strings, {len(s.wheels)} wheels, {s.t.size} samples to "
        f"{s.t_end:g} s; lands at roll, pitch, yaw "
        f"{', '.join(f'{math.degrees(v):+.2f}' for v in rpy)} deg, "
        f"{math.degrees(plan.landing_error_rad):.3f} deg from the target, turning "
        f"{math.degrees(plan.landing_rate_rad_s):.3f} deg/s (reduced model)"
    )
    travel = (s.rest_length.max(axis=0) - s.rest_length.min(axis=0)) * 1e3
    peak = abs(s.wheel_speed).max(axis=0) if s.wheels else []
    print(
        "servo travel "
        + (", ".join(f"{n} {v:.1f} mm" for n, v in zip(s.names, travel, strict=True)) or "none")
        + "; peak wheel speed "
        + (", ".join(f"{n} {v:.1f} rad/s" for n, v in zip(s.wheels, peak, strict=True)) or "none")
        + f"; planned in {plan.plan_time_s:.2f} s"
        + ("" if plan.success else f"; the optimiser did not converge: {plan.message}")
    )
