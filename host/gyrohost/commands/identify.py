"""``gyrotens identify LOG [LOG...] -o IDENT.toml [--config C] [--overlay FILE] [--params ...]``:
fit the rig's parameters to recorded runs (docs/identification.md)."""

import sys
import time
from pathlib import Path


def register(sub) -> None:
    from gyrohost.ident.groups import DEFAULT_GROUPS, FILTER_GROUPS, GROUPS

    p = sub.add_parser("identify", help="estimate the rig's parameters from run logs")
    p.add_argument("logs", type=Path, nargs="+", metavar="LOG", help="run log folders")
    p.add_argument("-o", "--out", type=Path, required=True, help="identified scene file (.toml)")
    p.add_argument(
        "--config",
        help="rig configuration (file or shipped name; default: the one the logs ran with)",
    )
    p.add_argument(
        "--overlay",
        type=Path,
        help="configuration overlay to write (default: IDENT-config.toml beside -o)",
    )
    p.add_argument(
        "--params",
        help=f"comma-separated parameter groups of {', '.join(GROUPS)} (docs/identification.md; "
        f"default {','.join(DEFAULT_GROUPS)}, with --method filter also "
        f"{','.join(FILTER_GROUPS)})",
    )
    p.add_argument(
        "--lengths",
        choices=("servos", "command"),
        default="servos",
        help="string lengths from the servos' reports (default) or the commands through the "
        "servos' lag",
    )
    p.add_argument(
        "--until",
        type=float,
        metavar="S",
        help="fit only the first S seconds of each log, from its lead-in",
    )
    p.add_argument(
        "--segment-s",
        type=float,
        default=4.0,
        metavar="S",
        help="output error: simulate in segments of S seconds (0: one simulation; 4)",
    )
    p.add_argument(
        "--segment-start",
        choices=("imu", "estimate"),
        default="imu",
        help="output error: a later segment starts from the IMU (default) or the logged estimate",
    )
    p.add_argument(
        "--method",
        choices=("staged", "output", "filter"),
        default="staged",
        help="staged (default): the output error, then the filter's likelihood for the IMU's "
        "mounting and latency and its own noise; output: the output error alone (simulate the "
        "log's inputs); filter: the filter's likelihood for every group (docs/identification.md)",
    )
    p.add_argument(
        "--weighed-to",
        type=float,
        default=0.001,
        metavar="KG",
        help="the resolution of the scale the scene's bars and wheels were weighed on "
        "(default 0.001 kg; 0: masses exact): the sigmas of J3, stiffness and damping include it",
    )
    p.add_argument(
        "--max-evaluations", type=int, default=40, help="of the residual per pass (default 40)"
    )
    p.add_argument(
        "--workers",
        type=at_least_one,
        metavar="N",
        help="the filter's likelihood: N parameter vectors at once in N processes (default: the "
        "cores)",
    )
    p.set_defaults(func=run)


def at_least_one(text: str) -> int:
    """An argparse type: an integer of at least 1."""
    import argparse

    n = int(text)
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {n}")
    return n


class FitProgress:
    """Progress of a fit: on a terminal a one-line bar (evaluations of the budget, cost), then a
    line of the statistics' counted steps (:meth:`statistics`); elsewhere (a log file, a
    pipe) a plain line every :attr:`every_s` seconds, so that a fit of many minutes shows it
    lives and about how long it may still take."""

    every_s = 10.0
    """Seconds between the plain lines: the long fits take minutes, a line per evaluation
    would bury the result."""

    def __init__(self, budget: int, stream=None, clock=time.monotonic):
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.clock = clock
        self.start_s = self.last_s = clock()
        self.budget, self.calls = budget, 0
        self.profiles, self.stats_calls = 0, 0

    def _due(self) -> bool:
        now = self.clock()
        if now - self.last_s < self.every_s:
            return False
        self.last_s = now
        return True

    def _left(self) -> str:
        """At most how long the fit may still take: its budget of evaluations left at the
        mean time per evaluation so far (the solver usually stops well before the budget)."""
        elapsed = self.clock() - self.start_s
        left = elapsed / self.calls * max(self.budget - self.calls, 0)
        return f"{elapsed:.0f} s so far, at most {left:.0f} s left"

    def __call__(self, simulations: int, cost: float) -> None:
        self.calls += 1
        if self.tty:
            frac = min(self.calls / self.budget, 1.0)
            bar = "#" * int(25 * frac)
            self.stream.write(
                f"\r[{bar:<25}] {self.calls:4d} evaluations, {simulations:4d} simulations, "
                f"cost {cost:.6g}  "
            )
            self.stream.flush()
        elif self._due():
            self.stream.write(
                f"fit: {self.calls} of at most {self.budget} evaluations, cost {cost:.6g}; "
                f"{self._left()}\n"
            )
            self.stream.flush()

    def statistics(self, step: str, done: int, total: int | None) -> None:
        """After every cost evaluation of the sigmas' profiles and the scale test
        (:func:`gyrohost.ident.profile.observing`): which step, how far."""
        if self.stats_calls == 0 and self.tty:
            self.stream.write("\n")  # the fit's bar stays as it ended
        self.stats_calls += 1
        if step == "profile" and done == 1:
            self.profiles += 1
        if step.startswith("profile"):
            what = f"cost {step} {self.profiles}"
        else:
            what = f"{step} refit"
        of = "" if total is None else f"/{total}"
        line = f"statistics: {what}, evaluation {done}{of}; {self.stats_calls:4d} in all"
        if self.tty:
            self.stream.write(f"\r{line}  ")
            self.stream.flush()
        elif self._due():
            elapsed = self.clock() - self.start_s
            self.stream.write(f"{line}; {elapsed:.0f} s so far\n")
            self.stream.flush()

    def close(self) -> None:
        if self.tty:
            self.stream.write("\n")


def run(args) -> int:
    from gyrohost.commands.errors import CliError
    from gyrohost.commands.replay import Warnings
    from gyrohost.config import ConfigError
    from gyrohost.estimator.config import for_rig
    from gyrohost.ident import filter_fit, report
    from gyrohost.ident.errors import IdentDataError, ParamsError
    from gyrohost.ident.fit import fit, nominal_lag, two_passes
    from gyrohost.ident.forward import STEP_S
    from gyrohost.ident.log_config import config_for_logs
    from gyrohost.ident.logs import log_warnings
    from gyrohost.ident.params import parameters
    from gyrohost.ident.servo_render import fitted_response
    from gyrohost.ident.weighing import with_weighing
    from gyrohost.ident.wheel_error import describe, wheel_walk
    from gyrohost.resources import ResourceError
    from gyrotensegrity import Model, SceneError, load_scene

    out = args.out
    if out.suffix != ".toml":
        raise CliError(f"-o {out}: the identified scene must be a .toml file")
    if not args.weighed_to >= 0.0:
        raise CliError(f"--weighed-to {args.weighed_to}: a scale's resolution is 0 kg or more")
    warn = Warnings("identify")
    for log in args.logs:
        for warning in log_warnings(log):
            print(f"gyrotens identify: warning: {warning}", file=sys.stderr)
    try:
        config, mismatches = config_for_logs(args.logs, args.config)
        for warning in mismatches:
            print(f"gyrotens identify: warning: {warning}", file=sys.stderr)
        for key in _noise_placeholders(config.source):
            print(
                f"gyrotens identify: warning: {config.source}: {key} is still the template's "
                "datasheet value, and the fit weighs its sensor by it: measure it with "
                "'gyrotens noise LOG' (docs/identification.md, step 2)",
                file=sys.stderr,
            )
        scene = load_scene(config.scene_path)
        est = for_rig(config)
        groups = _groups(args.params, args.method)
        if args.method == "filter":
            recs = [filter_fit.load(log, args.until, warn) for log in args.logs]
            for warning in filter(None, map(filter_fit.roll_over_warning, recs)):
                print(f"gyrotens identify: warning: {warning}", file=sys.stderr)
            for g in filter_fit.state_groups(est):
                if g in groups:
                    print(f"{g}: the filter's own state, not fitted")
                    groups.remove(g)
            params = parameters(scene, config, groups, est.servo_lag_s, len(recs), est, True)
        else:
            recs = _recordings(args, config, Model(scene), warn)
            params = parameters(scene, config, groups, nominal_lag(est, recs), len(recs), est)
    except (ConfigError, ResourceError, SceneError, IdentDataError, ParamsError) as exc:
        raise CliError(str(exc)) from None
    finally:
        warn.close()
    how = {"filter": "the filter's likelihood"}.get(args.method, "the output error")
    print(f"{len(recs)} recording(s); fitting {len(params)} parameters by {how}")
    if args.method == "filter":
        result = _fit(filter_fit.fit, (scene, config, est, params, recs), args, workers=True)
    else:
        _describe(recs)
        result = _fit(fit, (scene, config, est, params, recs), args, two_passes(recs, STEP_S))
    result = with_weighing(result, args.weighed_to)
    print("\n".join(report.report_lines(result)))
    _warn_undetermined(result)
    structure, config_used = None, config
    if args.method == "staged":
        structure, (result, config_used) = result, _refine(result, config, groups, args)
    walk = None if args.method == "filter" else wheel_walk(recs, est)
    if walk is not None:
        print(
            f"wheels' speed error (settled reports less commands, less the reports' noise): "
            f"{describe(walk)}; the filter's wheel walk {walk.psd:.3g} rad^2/s^3"
        )
    _write(args, result, config_used, structure, walk, fitted_response(recs))
    return 0


def _fit(fitter, problem: tuple, args, two: bool = False, workers: bool = False, line=None):
    """Run ``fitter`` on ``problem`` (scene, config, est, params, recs) with a progress line;
    ``two``: an output-error fit in two passes; ``workers``: a filter fit, on ``--workers``,
    started along ``line`` (:func:`gyrohost.ident.filter_fit.fit`)."""
    from gyrohost.commands.errors import CliError
    from gyrohost.ident import profile
    from gyrohost.ident.errors import FitError
    from gyrohost.ident.fit import latency_starts

    params = problem[3]
    starts = len(latency_starts(params, problem[2]))
    passes = 2 + len(profile.VALLEY_STEPS) if workers else starts + (1 if two else 0)
    kwargs = {"workers": args.workers, "line": line} if workers else {}
    progress = FitProgress(passes * args.max_evaluations * (len(params) + 1))
    try:
        with profile.observing(progress.statistics):
            return fitter(*problem, progress, args.max_evaluations, **kwargs)
    except FitError as exc:
        raise CliError(str(exc)) from None
    finally:
        progress.close()


def _refine(structure, config, groups, args):
    """The staged method's second stage (:mod:`gyrohost.ident.staged`): the filter's likelihood
    for the sensor from the output error's ``structure``; its result and the configuration it
    started from. The logs' rows left out were told by the first stage."""
    from gyrohost.commands.errors import CliError
    from gyrohost.config import ConfigError
    from gyrohost.estimator.errors import EstimatorConfigError
    from gyrohost.ident import filter_fit, report, staged
    from gyrohost.ident.errors import IdentDataError, ParamsError

    try:
        problem = staged.sensor_problem(structure, config, args.logs, groups, args.until)
    except (ConfigError, EstimatorConfigError, IdentDataError, ParamsError) as exc:
        raise CliError(str(exc)) from None
    span = min(args.until or staged.SENSOR_WINDOW_S, staged.SENSOR_WINDOW_S)
    print(
        f"then the sensor by the filter's likelihood: {len(problem[3])} parameters over the "
        f"first {span:g} s of each log"
    )
    line = staged.yaw_line(structure, problem[3])
    result = _fit(filter_fit.fit, problem, args, workers=True, line=line)
    print("\n".join(report.report_lines(result)))
    _warn_undetermined(result)
    return result, problem[1]


def _warn_undetermined(result) -> None:
    from gyrohost.ident import report

    loose = report.undetermined(result)
    if loose:
        print(
            "gyrotens identify: warning: not determined by the data (a 1-sigma of a factor e, "
            f"a radian or more, or no minimum): {', '.join(loose)}; the scene keeps their "
            "nominal values",
            file=sys.stderr,
        )


def _write(args, result, config, structure=None, walk=None, servo=None) -> None:
    """Write the identified scene (``structure``'s when the fit was staged, its header both
    stages' reports), the configuration overlay (``result``'s, on ``config``; a staged fit's
    keeps what the first stage determined and the second left; the wheels' walk ``walk``
    measured from the logs; the servos' response ``servo`` fitted to their reads) and the
    residuals' plots."""
    from gyrohost.ident import report

    out = args.out
    out.parent.mkdir(parents=True, exist_ok=True)
    first = structure if structure is not None else result
    later = result if structure is not None else None
    out.write_text(report.identified_scene(first, config, args.logs, later))
    overlay = args.overlay or out.with_name(out.stem + "-config.toml")
    overlay.parent.mkdir(parents=True, exist_ok=True)
    overlay.write_text(report.overlay_toml(result, config, structure, walk, servo))
    plot = out.with_name(out.stem + "-residuals.png")
    report.plot_residuals(first, plot)
    print(f"identified scene: {out}\nconfiguration overlay: {overlay}\nresiduals: {plot}")
    if later is not None:
        sensor_plot = out.with_name(out.stem + "-innovations.png")
        report.plot_residuals(later, sensor_plot)
        print(f"the filter's innovations: {sensor_plot}")
    print(f"run with it: gyrotens run --config {config.source} --overlay {overlay} --scene {out}")


def _groups(text: str | None, method: str) -> list[str]:
    """The parameter groups of ``--params`` (None: the default of ``method``)."""
    from gyrohost.ident.groups import DEFAULT_GROUPS, FILTER_GROUPS

    if text is None:
        return list(DEFAULT_GROUPS) + (list(FILTER_GROUPS) if method == "filter" else [])
    return [g.strip() for g in text.split(",") if g.strip()]


def _noise_placeholders(config_path: str) -> list[str]:
    """The estimator's noise keys the configuration file still has at the lab-rig template's
    datasheet values (:mod:`gyrohost.bringup.placeholders`), dotted; none when the file is
    gone (a log of another machine)."""
    from gyrohost.bringup.placeholders import find_placeholders
    from gyrohost.ident.noise import KEYS

    if not Path(config_path).is_file():
        return []
    keys = {f"estimator.{key}" for key in KEYS}
    return [p.key for p in find_placeholders(config_path) if p.key in keys]


def _recordings(args, config, model, warn) -> list:
    """The output-error fit's recordings of the logs (:func:`.logs.load_recording`), their
    rows left out told to ``warn``."""
    from gyrohost.ident.logs import load_recording

    n_wheels = len(model.wheel_bars)
    commanded = args.lengths == "command"
    return [
        load_recording(
            log, config, n_wheels, commanded, args.until, args.segment_s, args.segment_start, warn
        )
        for log in args.logs
    ]


def _describe(recs) -> None:
    """Print the output-error recordings' samples and how their string lengths were rendered."""
    print(f"{sum(len(r.t_imu_s) for r in recs)} IMU samples")
    for k, r in enumerate(recs, 1):
        if len(recs) > 1:
            print(f"recording {k}: {r.name} (its IMU biases: the parameters ending in [{k}])")
        if r.servo_response is not None:
            s = r.servo_response
            print(
                f"{r.name}: string lengths between the servo reports from the commands through "
                f"a delay of {1e3 * s.delay_s:.1f} ms and a lag of {1e3 * s.lag_s:.1f} ms "
                f"(reports less that: {1e3 * s.rms_m:.3f} mm RMS)"
            )
