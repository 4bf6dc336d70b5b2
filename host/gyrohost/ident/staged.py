"""The default identification: the output error for the structure, then the filter's likelihood
for the sensor.

The output error (:mod:`.fit`) simulates the log's inputs: quick, and smooth in J3, the strings'
stiffness and damping. But a motion nothing recorded, such as a fold of the D-bar growing from
its wheels' speed errors, is a residual it explains with whatever parameter correlates with it:
the IMU's yaw took up the roll such a fold adds to the gyro's reading during the pulls, a degree
off on held-out truths (reports/identification-heldout.md). The filter follows such motion (its
process noise lets the measurements steer it), so its likelihood (:mod:`.filter_fit`) measures
the IMU's mounting without it, and the noise scale the filter needs with the identified
structure; it is too slow and its cost too rough to fit the structure as well. So the filter
refines only :data:`SENSOR_GROUPS`, from the output error's values (the yaw from the smooth
minimum of its likelihood along it, :func:`yaw_line`), over the first :data:`SENSOR_WINDOW_S`
of each log.

The IMU's latency stays the output error's: the filter's likelihood steps by as much as the
latency's whole signal where a sample's time crosses a string's kink, and its fits landed 1.5 to
3.4 ms late on held-out truths (the output error's: -0.3 to +0.9 ms). The run's filter
carries the latency's error with its 1-sigma (``imu_latency_std_s``, the overlay); this one
keeps the rig's key (the simulated rigs' 0.2 ms of the host's wake-ups, a considered error):
with the output error's 1-sigma its likelihood would fit the model's errors as the latency's.
"""

from dataclasses import replace

from gyrohost.estimator.config import for_rig
from gyrohost.ident import filter_fit
from gyrohost.ident.params import parameters
from gyrohost.ident.report import apply_result

SENSOR_GROUPS = ("mounting", "process-noise")
"""What the filter refines: the IMU's mounting and its own noise scale. The IMU's biases are the
filter's states."""
LINE_PARAM = "mounting.yaw"
"""The parameter the filter starts from the smooth minimum along (:func:`.profile.line_start`):
the IMU's yaw, which gravity does not fix and the output error fixes only through the motion it
misfits (a degree or more off where it misfits, its sigma widened as much by the residuals'
correlation), while the filter's likelihood is smooth only near the rig's value."""
SENSOR_WINDOW_S = 5.0
"""Seconds of each log, from its lead-in, the filter refines over: the identify schedule's
first block of pulls, whose pitch rates carry the yaw, before the D-bar rolls over (past which
the filter's linearisation no longer holds it, :func:`.filter_fit.roll_over_warning`); about
a second per filter pass on the 2-core machine."""


def sensor_start(structure, config):
    """The rig configuration the filter starts from: ``config`` with the IMU's mounting and
    latency the output error found (:func:`.report.apply_result` of ``structure``; its
    nominal values where it left them undetermined), and the scene it identified."""
    a = apply_result(structure, config)
    estimator = {**config.estimator, "imu_latency_s": float(a.imu_latency_s)}
    imu = replace(config.imu, mounting_rpy_rad=tuple(float(v) for v in a.mounting_rpy_rad))
    return a.scene, replace(config, imu=imu, estimator=estimator)


def sensor_problem(structure, config, logs, groups, until_s=None, warn=None):
    """What the filter fits after ``structure`` (the output error's :class:`.fit.FitResult`):
    ``(scene, config, est, params, recs)`` for :func:`.filter_fit.fit`, the parameters those of
    :data:`SENSOR_GROUPS` in ``groups`` (the filter's own process noise always, where it
    takes any), the logs
    ``logs`` read over :data:`SENSOR_WINDOW_S` (or ``until_s`` if shorter)."""
    scene, start = sensor_start(structure, config)
    est = for_rig(start)
    window = SENSOR_WINDOW_S if until_s is None else min(until_s, SENSOR_WINDOW_S)
    recs = [filter_fit.load(log, window, warn) for log in logs]
    noisy = est.accel_psd_m2_s3 > 0.0  # a factor on no node noise leaves none
    refined = [g for g in SENSOR_GROUPS if g in groups or (g == "process-noise" and noisy)]
    params = parameters(scene, start, refined, est.servo_lag_s, len(recs), est, True)
    return scene, start, est, params, recs


def yaw_line(structure, params) -> tuple[int, float] | None:
    """``(index in params, sigma)`` of :data:`LINE_PARAM` for :func:`.filter_fit.fit`'s
    ``line``: its sigma the output error's ``structure`` gave it; None where the output error
    did not fit it or left it undetermined."""
    names = [p.name for p in structure.params]
    if LINE_PARAM not in names or LINE_PARAM not in [p.name for p in params]:
        return None
    i = names.index(LINE_PARAM)
    if not structure.determined[i]:
        return None
    return [p.name for p in params].index(LINE_PARAM), float(structure.sigma[i])
