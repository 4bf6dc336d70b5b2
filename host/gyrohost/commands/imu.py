"""``gyrotens imu calibrate``: the BWT61CL's accelerometer calibration, the IMU level and still
(docs/bring-up.md)."""

from gyrohost.commands.devices import add_device_options, say


def register(sub) -> None:
    p = sub.add_parser("imu", help="the IMU: calibrate its accelerometer")
    actions = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    c = actions.add_parser("calibrate", help="accelerometer calibration (IMU level and still)")
    add_device_options(c, "IMU")
    c.add_argument(
        "--wait", type=float, default=3.0, metavar="S", help="time given to the IMU (3 s)"
    )
    c.set_defaults(func=calibrate)


def calibrate(args) -> int:
    from gyrohost.bringup.devices import Target
    from gyrohost.bringup.imu_setup import calibrate_accelerometer
    from gyrohost.commands.errors import device_step

    target = Target(args.config, args.port)
    return device_step("imu", lambda: calibrate_accelerometer(target, say, wait_s=args.wait))
