"""``gyrotens noise LOG [LOG...] [--config C]``: the sensors' noise where the logs hold the rig
still, as the estimator's noise keys; the configuration is the one the logs ran with unless given
(docs/estimator.md#the-sensors-noise-on-the-rig-gyrotens-noise)."""

import sys
from pathlib import Path

ACCEL_BIAS_M_S2 = 0.05
"""The MPU6050's accelerometer bias after power-up (per axis), as the lab-rig template folds it."""


def register(sub) -> None:
    p = sub.add_parser("noise", help="measure the sensors' noise where run logs hold the rig still")
    p.add_argument("logs", type=Path, nargs="+", metavar="LOG", help="run log folders")
    p.add_argument(
        "--config",
        help="rig configuration (file or shipped name; default: the one the logs ran with)",
    )
    p.add_argument(
        "--accel-bias",
        type=float,
        default=ACCEL_BIAS_M_S2,
        metavar="M_S2",
        help="the accelerometer's bias left after its calibration, folded into its figure "
        f"(the filter has no state of it; default {ACCEL_BIAS_M_S2}, the datasheet's)",
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from gyrohost.commands.errors import CliError
    from gyrohost.config import ConfigError
    from gyrohost.estimator.config import for_rig
    from gyrohost.ident import noise
    from gyrohost.ident.errors import IdentDataError
    from gyrohost.ident.log_config import config_for_logs
    from gyrohost.resources import ResourceError

    if not args.accel_bias >= 0.0:
        raise CliError(f"--accel-bias {args.accel_bias}: must be at least 0 (m/s^2)")
    try:
        config, mismatches = config_for_logs(args.logs, args.config)
        for warning in mismatches:
            print(f"gyrotens noise: warning: {warning}", file=sys.stderr)
        est = for_rig(config)
        figures, windows = noise.measure(args.logs, est, args.accel_bias)
    except (ConfigError, ResourceError, IdentDataError) as exc:
        raise CliError(str(exc)) from None
    print("\n".join(noise.report_lines(figures, windows)))
    return 0
