"""Identification against a simulated truth whose errors are known (simulated clock, in process).

A truth that differs from the shipped D-bar: J3 x 1.3, bar mass x 0.8, string stiffness x 1.25,
damping x 0.7, the IMU mounted (3, -1.7, 1.1) degrees off, written as a scene and a copy of the
``sim-rig`` configuration pointing at it. Both scenes play :data:`EXCITATION` on the horizontal
string (pulls of 2 to 8 cm at 0.05 to 0.12 m/s with rests; the vertical string follows the
rhombus), recorded by :func:`gyrohost.sil.scoring.rig_model_run` (the rig's truth,
servos, IMU emulator and wheel-board emulator; seed = IMU noise and biases) and written as a run
log; :func:`identify_log` then fits it from the nominal configuration, string lengths from the
host's commands; :func:`errors` gives every parameter's error against the truth with its
reported 1-sigma, and :func:`coverage_lines` counts how often ``|error| <= 1 sigma`` (68 %
expected) and ``<= 2 sigma``. The tests record their small logs with it; the accuracy study
(``python -m studies.identify_check``) runs it over seeds.
"""

from dataclasses import replace
from pathlib import Path

import numpy as np

from gyrohost.estimator import streams
from gyrohost.resources import shipped

FACTORS = {"J3": 1.3, "bar_mass": 0.8, "stiffness": 1.25, "damping": 0.7}
"""The acceptance truth's parameters on the shipped D-bar's."""
IMU_ROTATION_DEG = (3.0, -1.7, 1.1)
"""The acceptance truth's IMU mounting: roll, pitch, yaw, degrees."""
MOUNTING_RPY_RAD = tuple(np.radians(IMU_ROTATION_DEG))
ROD_M = 0.3048  # the D-bar's bar length (dbar-gyro)
EXCITATION = [  # (change of the horizontal string from its initial length, m; duration, s)
    (-0.03, 0.25), (-0.03, 0.3), (0.0, 0.6), (0.0, 0.3), (-0.06, 0.5), (-0.06, 0.2),
    (-0.02, 0.4), (-0.02, 0.3), (-0.08, 0.6), (-0.08, 0.3), (0.0, 0.7), (0.0, 0.3),
]  # fmt: skip
GROUPS = ("J3", "bar-mass", "stiffness", "damping", "mounting", "gyro-bias", "accel-bias")
"""The servo lag is left at the estimator's (the rig models' servos): fitted with the strings'
stiffness and damping it takes their part (docs/identification.md)."""


def _vec(v) -> str:
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def write_rigs(
    folder: Path,
    duration_s: float | None = None,
    weighed: bool = False,
    repeat: int = 1,
    speed_error_std_rad_s: float = 0.0,
) -> tuple[Path, Path]:
    """The nominal and the truth rig configurations (and their scenes) in ``folder``;
    ``duration_s`` cuts the excitation short; ``weighed``: the nominal scene has the truth's
    bar mass (the bars weighed); ``repeat``: the excitation played that many times (the truth
    rolls over about 8 s in); ``speed_error_std_rad_s``: the emulated wheels' speed-loop error
    (:func:`wheel_speed_error`). Returns (nominal config, truth config)."""
    text = Path(shipped("scene", "dbar-gyro")).read_text()
    head = text.partition("[[strings]]")[0]
    L0 = 0.43105229381822
    t, v = [0.0, 0.3], [L0, L0]
    for change, dur in EXCITATION * repeat:
        t.append(t[-1] + dur)
        v.append(L0 + change)
    t, v = np.array(t), np.array(v)
    if duration_s is not None:
        v = np.interp(np.append(t[t < duration_s], duration_s), t, v)
        t = np.append(t[t < duration_s], duration_s)
    vertical = np.sqrt(4 * ROD_M**2 - v**2)  # the rhombus' other diagonal
    J3 = 0.5 * 0.05 * 0.031**2

    def scene(k, c, mass, j3):
        strings = "".join(
            f'\n[[strings]]\nname = "{n}"\nnodes = {nodes}\nstiffness = {k!r}\ndamping = {c!r}\n'
            f"rest_length = {{ t = {_vec(t)}, value = {_vec(r)} }}\n"
            for n, nodes, r in (("s13", '["n1", "n3"]', v), ("s24", '["n2", "n4"]', vertical))
        )
        body = head.replace("duration = 3.0", f"duration = {float(t[-1])!r}")
        body = body.replace("mass = 0.10", f"mass = {mass!r}")
        return body.replace("spin = ", f"J3 = {j3!r}, spin = ") + strings

    f = FACTORS
    nominal_mass = 0.1 * f["bar_mass"] if weighed else 0.1
    (folder / "nominal.toml").write_text(scene(200.0, 2.0, nominal_mass, J3))
    (folder / "truth.toml").write_text(
        scene(200.0 * f["stiffness"], 2.0 * f["damping"], 0.1 * f["bar_mass"], J3 * f["J3"])
    )
    config = wheel_speed_error(
        Path(shipped("config", "sim-rig")).read_text(), speed_error_std_rad_s
    )
    nominal, truth = folder / "nominal-rig.toml", folder / "truth-rig.toml"
    nominal.write_text(config.replace('scene = "dbar-gyro"', 'scene = "nominal.toml"'))
    truth.write_text(
        with_true_mounting(config.replace('scene = "dbar-gyro"', 'scene = "truth.toml"'))
    )
    return nominal, truth


def wheel_speed_error(config_text: str, std_rad_s: float) -> str:
    """The shipped ``sim-rig`` configuration's text with the emulated wheels' speed-loop error
    ``[sim.wheels] speed_error_std_rad_s`` set to ``std_rad_s``.

    The identification's acceptance is taken on wheels that hold their speeds exactly (0): a
    speed error as small as the default 0.01 rad/s excites the D-bar's unstable roll mode in
    the truth, which a forward model on held speeds does not follow
    (docs/identification.md#limits)."""
    table = "[sim.wheels]\n"
    if table not in config_text:
        raise ValueError("the sim-rig configuration has no [sim.wheels] table")
    return config_text.replace(table, f"{table}speed_error_std_rad_s = {std_rad_s!r}\n", 1)


def with_true_mounting(config_text: str) -> str:
    """A shipped rig configuration's text with the truth's IMU mounting
    (:data:`MOUNTING_RPY_RAD`)."""
    zero = "mounting_rpy_rad = [0.0, 0.0, 0.0]"
    return config_text.replace(zero, f"mounting_rpy_rad = {_vec(MOUNTING_RPY_RAD)}")


def record_log(truth_config: Path, seed: int, folder: Path) -> Path:
    """One run of the truth's scene on the rig's models, written as a run log in ``folder``."""
    from gyrohost.config import load_rig_config
    from gyrohost.sil.scoring import rig_model_run
    from gyrotensegrity import load_scene

    config = load_rig_config(truth_config)
    duration = load_scene(config.scene_path).duration
    _, data, *_ = rig_model_run(config, seed, duration)
    return write_log(data, folder)


def write_log(data: dict, folder: Path) -> Path:
    """The streams ``data`` of an in-process run (:func:`gyrohost.sil.scoring.rig_model_run`)
    as a run log in ``folder``, its ``lead_in`` phase from 0 to the last IMU sample."""
    from gyrohost.run.log import RunLog

    with RunLog(folder, {"source": "identify_check"}) as log:
        events = log.stream("events", ["t_s", "kind", "message"], ("kind", "message"))
        events.write(0.0, "phase", "lead_in")
        for name in (streams.IMU, streams.WHEELS, streams.SERVOS, streams.COMMAND):
            s = log.stream(name, data[name].dtype.names)
            for row in data[name]:
                s.write(*row)
        events.write(float(data[streams.IMU]["t_s"][-1]) + 0.01, "phase", "rampdown")
    return folder


def identify_log(nominal_config: Path, logs, groups=GROUPS, segment_s=0.0, commanded=True):
    """Fit ``groups`` to the logs from the nominal configuration (:func:`fit_inputs`)."""
    from gyrohost.ident.fit import fit

    return fit(*fit_inputs(nominal_config, logs, groups, segment_s, commanded))


def identify_filter(nominal_config: Path, logs, groups=GROUPS, workers: int | None = 1):
    """Fit ``groups`` (less the filter's own states, ``filter_fit.state_groups``) to the logs
    from the nominal configuration by the filter's prediction error
    (:mod:`gyrohost.ident.filter_fit`), the filter tuned as the simulated-clock SIL tunes it
    for the rig models (:data:`gyrohost.sil.scoring.RIG_MODEL_KEYS`), in ``workers`` processes
    (None: one per usable core)."""
    from gyrohost.config import load_rig_config
    from gyrohost.estimator.config import config_from_dict
    from gyrohost.ident import filter_fit
    from gyrohost.ident.params import parameters
    from gyrohost.sil.emulator_keys import emulator_keys
    from gyrohost.sil.scoring import RIG_MODEL_KEYS
    from gyrotensegrity import load_scene

    config = load_rig_config(nominal_config)
    scene = load_scene(config.scene_path)
    est = config_from_dict({**emulator_keys(config), **RIG_MODEL_KEYS})
    recs = [filter_fit.load(log) for log in logs]
    groups = [g for g in groups if g not in filter_fit.state_groups(est)]
    params = parameters(scene, config, groups, est.servo_lag_s, len(recs), est, True)
    return filter_fit.fit(scene, config, est, params, recs, workers=workers)


def fit_inputs(nominal_config: Path, logs, groups=GROUPS, segment_s=0.0, commanded=True):
    """What :func:`gyrohost.ident.fit.fit` takes to fit ``groups`` to the logs from the nominal
    configuration: string lengths from the host's commands (``commanded``, else the servos'
    reports), each log simulated in segments of ``segment_s`` (0: one).

    Returns
    -------
    scene, config, est, params, recs
    """
    from gyrohost.config import load_rig_config
    from gyrohost.estimator.config import EXACT_IMU_TIMES, for_rig
    from gyrohost.ident.fit import nominal_lag
    from gyrohost.ident.logs import load_recording
    from gyrohost.ident.params import parameters
    from gyrotensegrity import Model, load_scene

    config = load_rig_config(nominal_config)
    scene = load_scene(config.scene_path)
    # the rig models' IMU samples stamped when taken
    est = replace(for_rig(config), **EXACT_IMU_TIMES)
    n_w = len(Model(scene).wheel_bars)
    recs = [
        load_recording(log, config, n_w, commanded=commanded, segment_s=segment_s) for log in logs
    ]
    params = parameters(scene, config, list(groups), nominal_lag(est, recs), len(recs), est)
    return scene, config, est, params, recs


def errors(result, weighed=False) -> dict[str, tuple[float, float]]:
    """Parameter -> (error against the truth, reported 1-sigma), log factors for the scaled
    parameters (about relative), rad for the mounting; a parameter the fit reports as not
    separable is left out, and each determined combination of such parameters is in, named
    after its first parameter (``J3 | scale``: J3 against the bars' mass along the scale)."""
    truth = {k: np.log(v) for k, v in FACTORS.items()}
    truth["bar_mass"] = 0.0 if weighed else truth["bar_mass"]
    truth["servo_lag"] = 0.0  # the rig models' servos: the estimator's lag (its nominal)
    axes = ("roll", "pitch", "yaw")
    truth.update({f"mounting.{a}": m for a, m in zip(axes, MOUNTING_RPY_RAD, strict=True)})
    true_theta = np.array([truth.get(p.name, np.nan) for p in result.params])
    out = {
        p.name: (float(result.theta[i] - truth[p.name]), float(result.sigma[i]))
        for i, p in enumerate(result.params)
        if p.name in truth and result.separable[i]
    }
    for c, value, sigma in result.combinations:
        used = np.flatnonzero(c)
        if not np.all(np.isfinite(true_theta[used])):
            continue
        name = result.params[int(np.flatnonzero(c > 0)[0])].name
        out[f"{name} | scale"] = (float(value - c[used] @ true_theta[used]), float(sigma))
    return out


def coverage_lines(rows: list[dict], units: str) -> list[str]:
    """The coverage table of ``rows`` (per seed, parameter -> (error, reported 1-sigma), in
    ``units``): per parameter the mean and largest error, the mean sigma, and how often the
    error lies within 1 and 2 sigmas."""
    lines = [f"{'parameter':<18}{'mean |error|':>14}{'max |error|':>13}{'mean sigma':>12}"
             f"{'<= 1 sigma':>12}{'<= 2 sigma':>12}"]  # fmt: skip
    for name in dict.fromkeys(k for r in rows for k in r):
        e = np.array([abs(r[name][0]) for r in rows if name in r])
        s = np.array([r[name][1] for r in rows if name in r])
        lines.append(f"{name:<18}{e.mean():14.4f}{e.max():13.4f}{s.mean():12.4f}"
                     f"{np.mean(e <= s):12.0%}{np.mean(e <= 2 * s):12.0%}")  # fmt: skip
    lines.append(f"({units}; expected coverage 68 % and 95 %, {len(rows)} seeds)")
    return lines
