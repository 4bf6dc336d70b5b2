"""The error of the IMU's latency as a state: a random constant whose prior is how well the
latency is known (``imu_latency_std_s``, e.g. ``gyrotens identify``'s 1-sigma of it).

The host places each sample ``imu_latency_s`` before its stamp. A latency off by ``d`` puts
every sample of the run ``d`` late, the same for the whole run, where the filter's model of a
spinning D-bar turns fast: 0.1 ms of it leaves the node positions several times their spread
(docs/estimator-noise.md, "The IMU's latency"). A white time noise (``imu_time_std_s``) does
not describe a constant; the state does, and the measurements see it through the motion: a
sample taken ``d`` earlier than the filter takes it reads ``h - d dh/dt``, so each IMU source's
Jacobian gets the column ``-dh/dt`` and its prediction the estimate's ``-d dh/dt``
(the attitude's rotation vector: ``-w``, the sensor's angular velocity in world axes, and
``+d w`` on the sample's side, as :mod:`.fuse_imu_angle` takes the filter's lag).
"""

from dataclasses import replace

from . import fuse_imu_accel, fuse_imu_angle, fuse_imu_rate
from .imu_prediction import ImuPrediction


def with_latency_error(ekf, pred: ImuPrediction, measurements) -> list:
    """The IMU sample's ``measurements`` (rate, specific force, attitude) with the latency
    error's column and its estimate, where it is a state (``ekf.layout.imu_latency``)."""
    L = ekf.layout
    if not L.n_imu_latency:
        return list(measurements)
    d = float(ekf.x[L.imu_latency.start])
    rates = {
        fuse_imu_rate.SOURCE: pred.d_omega @ pred.x_dot,
        fuse_imu_accel.SOURCE: pred.d_specific_force @ pred.x_dot,
        fuse_imu_angle.SOURCE: fuse_imu_angle.rotation_jacobian(pred.R_ws, pred.dR_ws) @ pred.x_dot,
    }
    out = []
    for m in measurements:
        h_dot = rates[m.source]
        H = m.H.copy()
        H[:, L.imu_latency.start] = -h_dot
        if m.source == fuse_imu_angle.SOURCE:
            out.append(replace(m, z=m.z + d * h_dot, H=H))
        else:
            out.append(replace(m, hx=m.hx - d * h_dot, H=H))
    return out
