"""``gyrotens sil [--runs N] [--realtime] [--config C] [--overlay FILE] [--scene S]
[--truth-scene T] [--workers N]``: the estimator's consistency.

Runs the paper's schedule ``N`` times on the simulated rig (in process on a simulated clock, or
``--realtime`` through the run loop) and prints NEES and the NIS of every source against the
95 % bounds of an N-run average, the share of time steps inside them, tilt and node errors and
the filter's CPU time (:mod:`gyrohost.sil.scoring`, docs/estimator.md). The
simulated clock's runs go through :mod:`gyrohost.parallel` with ``--workers`` or ``--scheduler``.
"""


def register(sub) -> None:
    from gyrohost.sil.options import add_arguments

    p = sub.add_parser("sil", help="estimator consistency on the simulated rig (NEES, NIS)")
    add_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from gyrohost.commands.errors import CliError, executor_status
    from gyrohost.errors import ConfigError
    from gyrohost.estimator.errors import EstimatorConfigError
    from gyrohost.parallel import ExecutorError
    from gyrohost.resources import ResourceError
    from gyrohost.run import ScheduleRefused
    from gyrohost.run.errors import LogError
    from gyrohost.sil.errors import SilError
    from gyrohost.sil.scoring import report
    from gyrotensegrity import SceneError

    if args.runs is not None and args.runs < 1:
        raise CliError(f"--runs must be at least 1, got {args.runs}")
    if args.realtime and (args.workers is not None or args.scheduler is not None):
        raise CliError("--realtime runs one after the other: --workers/--scheduler are for the "
                       "simulated clock")  # fmt: skip
    try:
        report(args)
    except (SilError, ScheduleRefused, EstimatorConfigError, ConfigError, ResourceError,
            SceneError) as exc:  # fmt: skip
        raise CliError(str(exc)) from None  # bad input: a message, exit 2
    except LogError as exc:  # --score-only: a run folder missing or damaged
        raise CliError(f"{exc} (--score-only scores the runs --realtime recorded there)") from None
    except ExecutorError as exc:
        return executor_status("sil", exc)
    return 0
