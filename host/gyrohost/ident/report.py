"""What ``gyrotens identify`` writes: the identified scene, the configuration overlay, the text
report and the residual plot."""

from pathlib import Path

import numpy as np

from gyrohost.ident.fit import BAR_GROUPS, INVOLVED, FitResult, latency_index
from gyrohost.ident.params import apply
from gyrohost.ident.profile import VALLEY_STEP
from gyrohost.ident.scenefile import scene_toml
from gyrohost.ident.weighing import SCALED
from gyrohost.ident.wheel_error import describe


def report_lines(result: FitResult) -> list[str]:
    """The fit as text: every parameter with its 1-sigma, the strong correlations, the
    combinations the data do not separate, the residual RMS per stream."""
    lines = [f"{'parameter':<22}{'nominal':>14}{'identified':>14}{'1-sigma':>12}  unit"]
    determined = result.determined
    for i, p in enumerate(result.params):
        if determined[i]:
            est, sig = f"{result.value(i):14.6g}", f"{result.value_sigma(i):12.3g}"
        else:
            why = "not separable" if not result.separable[i] else "undetermined"
            est, sig = f"{why:>14}", f"{'':>12}"
        rel = (
            f" ({100 * (np.exp(result.theta[i]) - 1):+.1f} %)"
            if p.relative and determined[i]
            else ""
        )
        lines.append(f"{p.name:<22}{p.nominal:14.6g}{est}{sig}  {p.unit}{rel}")
    names = [p.name for p in result.params]
    for a, b, r in result.strong_correlations():
        lines.append(f"correlation {a} / {b}: {r:+.3f}")
    for v in result.unresolved:
        lines.append("not determined by the data: " + _combination(v, names))
    for c, value, sigma in result.combinations:
        lines.append(f"determined: {_combination(c, names)} = {value:+.4g} (1-sigma {sigma:.2g})")
    if result.scale_valley is not None:
        lines.append(
            "the common scale of the masses, inertias, stiffness and damping is not determined "
            "(weigh the bars): the scene keeps the bars' nominal and moves the others with it"
        )
    if result.unresolved:
        lines.append("(log factors for J3, masses, inertias, stiffness, damping; else absolute)")
    lines += _fit_quality(result) + _sigma_notes(result)
    if result.strings_valley:
        optima = ", ".join(f"{k:+.2f}: {c:.1f}" for k, c in result.strings_valley)
        lines.append(
            f"strings' valley (offset in steps of stiffness x{np.exp(VALLEY_STEP[0]):.3f} and "
            f"damping x{np.exp(VALLEY_STEP[1]):.3f}: cost at its optimum): {optima}; "
            f"fitted from its parabola's vertex, cost {result.cost:.1f}"
        )
    if result.latency_starts:
        starts, costs, ends = zip(*result.latency_starts, strict=True)
        best = int(np.argmin(costs))
        lines.append(
            f"imu_latency: the first solve started at {len(starts)} latencies from "
            f"{1e3 * starts[0]:.1f} to {1e3 * starts[-1]:.1f} ms (costs {min(costs):.1f} to "
            f"{max(costs):.1f}); the lowest from {1e3 * starts[best]:.1f} ms, at "
            f"{1e3 * ends[best]:.2f} ms"
        )
    if result.start_line is not None:
        name, start, samples = result.start_line
        offsets, costs = zip(*samples, strict=True)
        lines.append(
            f"{name} started {start:+.4g} from its nominal: the smooth minimum of the cost "
            f"along it from {offsets[0]:+.4g} to {offsets[-1]:+.4g} (costs {min(costs):.1f} "
            f"to {max(costs):.1f})"
        )
    for name, t0, t1 in result.dropped:
        lines.append(f"not fitted (the prediction does not follow it): {name} {t0:.1f}-{t1:.1f} s")
    lines.append(f"{result.nfev} evaluations: {result.status}")
    return lines


def _fit_quality(result: FitResult) -> list[str]:
    """How well the fit follows the log: the residual RMS per stream and the weighted
    residuals' variance per degree of freedom."""
    lines = [
        f"residual RMS {name}: nominal {before:.4g}, identified {after:.4g}"
        for name, (before, after) in result.rms.items()
    ]
    if np.isfinite(result.residual_variance):
        lines.append(
            f"residual variance per degree of freedom {result.residual_variance:.3g} (near 1 "
            "where the fit follows the log to the sensors' noise)"
        )
    return lines


def _sigma_notes(result: FitResult) -> list[str]:
    """What widened the sigmas: the segments' spread, the residuals' correlation, the
    weighing."""
    lines = [
        f"1-sigma of {name} widened {ratio:.2f} times: the segments disagree about it "
        "beyond their noise"
        for name, ratio in result.widened.items()
    ]
    wide = [f"{name} x{f:.2f}" for name, f in result.correlated.items() if round(f, 2) > 1.0]
    if wide:
        lines.append(
            f"residuals correlated over {result.correlation_lags} IMU samples: 1-sigma widened "
            f"{', '.join(wide)} (where the segments' spread widens one more, that applies)"
        )
    if result.weighing_sigma is not None:
        added = ", ".join(
            f"{p.name} {100 * w:.2f} %"
            for p, w in zip(result.params, result.weighing_sigma, strict=True)
            if p.group in SCALED
        )
        lines.append(
            f"1-sigma includes the weighing (the motion fixes these relative to the masses): "
            f"{added}"
        )
    return lines


def undetermined(result: FitResult) -> list[str]:
    """Names of the separable parameters the fit did not determine (``FitResult.determined``)."""
    loose = result.separable & ~result.determined
    return [p.name for p, no in zip(result.params, loose, strict=True) if no]


def _combination(v: np.ndarray, names: list[str]) -> str:
    terms = [f"{c:+.3f} {n}" for c, n in zip(v, names, strict=True) if abs(c) > 0.05]
    return " ".join(terms)


def overlay_toml(
    result: FitResult, config, before: FitResult | None = None, walk=None, servo=None
) -> str:
    """The rig configuration keys the fit changes: the IMU's mounting, each fitted servo's
    ``length_at_zero_m`` (its zero offset added); the mounting's covariance for the estimator
    (:func:`mounting_covariance`). Determined parameters only, or those of ``before`` (an
    earlier stage, whose values ``config`` carries) where ``result`` leaves them; with
    ``walk`` (:class:`.wheel_error.WheelWalk`) the filter's wheel walk measured from the
    logs; with ``servo`` (:class:`.servo_render.ServoResponse`) the filter's servo lag
    fitted to the servos' reads."""
    a = apply_result(result, config)
    fitted = _determined_groups(result) | _determined_groups(before)
    out = ["# gyrotens identify: keys to merge into the rig configuration (docs/identification.md)"]
    if "mounting" in fitted:
        out += ["[imu]", f"mounting_rpy_rad = {_array(a.mounting_rpy_rad)}"]
    cov = _latest(mounting_covariance, result, before)
    latency_std = _latest(latency_sigma, result, before)
    estimator = _estimator_keys(result, a, fitted, cov, latency_std)
    estimator += _string_keys(_latest(string_covariance, result, before))
    estimator += _j3_keys(_latest(j3_variance, result, before))
    if servo is not None:
        estimator += [
            f"servo_lag_s = {float(servo.lag_s)!r}  # fitted to the servos' reads (reads less "
            f"the response {1e3 * servo.rms_m:.3f} mm RMS)",
            f"servo_delay_s = {max(float(servo.delay_s), 0.0)!r}  # with the lag",
        ]
    if walk is not None:
        estimator.append(
            f"wheel_accel_psd_rad2_s3 = {float(walk.psd)!r}  # the wheels' speed error "
            f"measured from the logs: {describe(walk)}"
        )
    if estimator:
        out += ["", "[estimator]", *estimator]
    if "servo-offsets" in fitted:
        servos = [s for s in config.servos.servo if s.string]
        for s, offset in zip(servos, a.offsets_m, strict=True):
            out += ["", "[[servos.servo]]", f'name = "{s.name}"']
            out.append(f"length_at_zero_m = {float(s.length_at_zero_m + offset)!r}")
    return "\n".join(out) + "\n"


def _latest(of, result: FitResult, before: FitResult | None):
    """``of(result)``, or where that is None, ``of(before)`` (an earlier stage's, or None)."""
    value = of(result)
    return of(before) if value is None and before is not None else value


def _determined_groups(result: FitResult | None) -> set:
    if result is None:
        return set()
    return {p.group for p, ok in zip(result.params, result.determined, strict=True) if ok}


def _estimator_keys(result: FitResult, a, fitted: set, cov, latency_std) -> list[str]:
    """The overlay's ``[estimator]`` lines: the mounting's covariance ``cov`` (or None), and
    the filter's own latency (with its 1-sigma ``latency_std``, or None) and noise where the fit
    determined them."""
    lines = []
    if cov is not None:
        lines += [
            "# how well the fit knows the mounting's roll, pitch, yaw (rad^2): the EKF carries",
            "# its error (docs/estimator.md)",
            f"imu_mounting_cov_rad2 = {_matrix(cov)}",
        ]
    if "imu-latency" in fitted:
        lines.append(f"imu_latency_s = {float(a.imu_latency_s)!r}  # fitted by gyrotens identify")
        if latency_std is not None:  # the filter carries the latency's error as a state
            lines.append(f"imu_latency_std_s = {latency_std!r}  # the fitted latency's 1-sigma")
    if "process-noise" in fitted:
        nominal = next(p.nominal for p in result.params if p.group == "process-noise")
        psd = float(nominal * a.accel_psd_factor)
        lines.append(f"accel_psd_m2_s3 = {psd!r}  # fitted by the likelihood")
    return lines


def _string_keys(cov) -> list[str]:
    """The overlay's lines of the strings' stiffness and damping covariance ``cov`` (None:
    none)."""
    if cov is None:
        return []
    return [
        "# how well the fit knows the strings' stiffness and damping (their log factors,",
        "# squared): the EKF carries their errors (docs/estimator.md)",
        f"string_cov_rel2 = {_matrix(cov)}",
    ]


def _j3_keys(variance) -> list[str]:
    """The overlay's line of the wheels' J3 variance ``variance`` (None: none)."""
    if variance is None:
        return []
    return [
        f"j3_var_rel2 = {variance!r}  # how well the fit knows J3 (its log factor, squared): "
        "the EKF carries its error"
    ]


def _array(values) -> str:
    return f"[{', '.join(repr(float(x)) for x in values)}]"


def _matrix(rows) -> str:
    return f"[{', '.join(_array(row) for row in rows)}]"


def mounting_covariance(result: FitResult):
    """Covariance (3, 3), rad^2, of the fitted mounting's roll, pitch and yaw (from their
    1-sigmas and correlations); None unless all three were fitted and are determined."""
    idx = [i for i, p in enumerate(result.params) if p.group == "mounting"]
    if len(idx) != 3:
        return None
    return _covariance(result, idx, [result.value_sigma(i) for i in idx])


def string_covariance(result: FitResult):
    """Covariance (2, 2) of the fitted stiffness's and damping's log factors (relative
    1-sigmas and their correlation); None unless both were fitted and are determined."""
    names = [p.name for p in result.params]
    if "stiffness" not in names or "damping" not in names:
        return None
    idx = [names.index("stiffness"), names.index("damping")]
    return _covariance(result, idx, result.sigma[idx])


def j3_variance(result: FitResult) -> float | None:
    """The variance of the fitted J3's log factor (its relative 1-sigma, squared); None unless
    the one J3 of every wheel was fitted and is determined."""
    names = [p.name for p in result.params]
    if "J3" not in names or not result.determined[names.index("J3")]:
        return None
    return float(result.sigma[names.index("J3")] ** 2)


def latency_sigma(result: FitResult) -> float | None:
    """The fitted IMU latency's 1-sigma, s; None unless it was fitted and is determined."""
    i = latency_index(result.params)
    if i is None or not result.determined[i]:
        return None
    return float(result.value_sigma(i))


def _covariance(result: FitResult, idx, sigma):
    """The covariance of the parameters ``idx`` with 1-sigmas ``sigma`` and the fit's
    correlations; None unless every one is determined (its sigma finite and below 1)."""
    if not np.all(result.determined[idx]):
        return None
    return result.correlation[np.ix_(idx, idx)] * np.outer(sigma, sigma)


def apply_result(result: FitResult, config):
    """:func:`.params.apply` of the estimate, parameters not determined (or not fitted, as the
    configuration's IMU latency) at their nominal; with an undetermined common scale, the
    estimate moved along it until the bars' parameter is at its nominal (the same motion), the
    others where that leaves them."""
    theta = result.theta
    valley = result.scale_valley
    if valley is not None:
        ref = next(i for i, p in enumerate(result.params) if p.group in BAR_GROUPS)
        theta = theta - theta[ref] / valley[ref] * valley
        keep = result.determined | (np.abs(valley) > INVOLVED)
    else:
        keep = result.determined
    theta = np.where(keep, theta, 0.0)
    latency_s = float(config.estimator.get("imu_latency_s", 0.0))  # where the fit left it
    return apply(result.scene, config, result.params, theta, result.servo_lag_s, 1, latency_s)


def identified_scene(result: FitResult, config, logs, later: FitResult | None = None) -> str:
    """The complete scene file of the estimate (parameters not determined left nominal); its
    header the fit's report, then that of a ``later`` stage, which refined the sensor only
    (:func:`read_identified` reads the later value of a parameter both give)."""
    scene = apply_result(result, config).scene
    lines = [f"Identified by gyrotens identify from {', '.join(map(str, logs))}"]
    lines += report_lines(result)
    if later is not None:
        lines += ["then the sensor by the filter's likelihood:", *report_lines(later)]
    return scene_toml(scene, "\n".join(lines))


def read_identified(text: str) -> dict[str, tuple[float, float]]:
    """Parameter -> (identified value, 1-sigma) as an identified scene's header gives them
    (:func:`identified_scene`, to :func:`report_lines`' digits; the parameters reported not
    separable or not determined left out)."""
    out = {}
    for line in text.splitlines():
        words = line.removeprefix("# ").split()
        if not line.startswith("# ") or len(words) < 4:
            continue
        try:
            out[words[0]] = (float(words[2]), float(words[3]))
        except ValueError:  # the column header, a row not determined, the other lines
            continue
    return out


def plot_residuals(result: FitResult, path: Path) -> None:
    """One panel per stream: measured less predicted, nominal (grey) and identified, every
    channel, all recordings one after the other."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(result.streams), 1, figsize=(9, 7), sharex=True)
    units = {"gyro": "rad/s", "accel": "m/s^2", "angle": "rad"}
    for ax, (name, cols) in zip(axes, result.streams.items(), strict=True):
        before = np.concatenate(result.initial_residuals)[:, cols]
        after = np.concatenate(result.residuals)[:, cols]
        k = np.arange(len(after)) * 0.01
        for j in range(after.shape[1]):
            ax.plot(k, before[:, j], color="0.8", lw=0.6)
        for j, label in enumerate(result.channels[cols]):
            ax.plot(k, after[:, j], lw=0.8, label=label)
        ax.set_ylabel(f"{name}, {units[name]}")
        ax.legend(loc="upper right", fontsize=7, ncol=3)
    axes[-1].set_xlabel("IMU sample x 10 ms (recordings one after the other)")
    axes[0].set_title("residuals, measured less predicted: nominal (grey), identified")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
