"""The error of the IMU's latency as a state: a random constant whose prior is how well the
latency is known (``imu_latency_std_s``, e.g. ``gyrotens identify``'s 1-sigma of it).

The host places each sample ``imu_latency_s`` before its stamp. A latency off by ``d`` puts
every sample of the run ``d`` late, the same for the whole run, where the filter's model of a
spinning D-bar turns fast: 0.1 ms of it leaves the node positions several times their spread
(docs/estimator-noise.md, "The IMU's latency"). A white time noise (``imu_time_std_s``) does
not describe a constant; the state does, and the measurements see it through the motion: a
sample taken ``d`` earlier than the filter takes it reads ``h - d dh/dt``. The estimate of ``d``
therefore adds to the filter's lag behind the sample (:func:`sample_lag_s`), which every IMU
prediction already takes back along the dynamics (:func:`.imu_prediction.at_sample_time`, the
attitude's on the sample's side), and each source's Jacobian gets the column ``-dh/dt`` (the
attitude's rotation vector: ``-w``, the sensor's angular velocity in world axes).
"""

from dataclasses import replace

from . import fuse_imu_accel, fuse_imu_angle, fuse_imu_rate
from .imu_prediction import ImuPrediction


def sample_lag_s(ekf, taken_s: float) -> float:
    """How far the filter at ``ekf.t`` is ahead of when a sample placed at ``taken_s`` was
    taken, s: ahead of ``taken_s`` (none where it has still to predict to it), and by the
    estimated error of the latency (``ekf.layout.imu_latency``, where it is a state)."""
    L = ekf.layout
    lag = max(ekf.t - taken_s, 0.0)
    return lag + float(ekf.x[L.imu_latency.start]) if L.n_imu_latency else lag


def with_latency_columns(ekf, pred: ImuPrediction, measurements) -> list:
    """The IMU sample's ``measurements`` (rate, specific force, attitude) with the latency
    error's Jacobian column, where it is a state."""
    L = ekf.layout
    if not L.n_imu_latency:
        return list(measurements)
    rates = {
        fuse_imu_rate.SOURCE: pred.d_omega @ pred.x_dot,
        fuse_imu_accel.SOURCE: pred.d_specific_force @ pred.x_dot,
        fuse_imu_angle.SOURCE: fuse_imu_angle.rotation_jacobian(pred.R_ws, pred.dR_ws) @ pred.x_dot,
    }
    out = []
    for m in measurements:
        H = m.H.copy()
        H[:, L.imu_latency.start] = -rates[m.source]
        out.append(replace(m, H=H))
    return out
