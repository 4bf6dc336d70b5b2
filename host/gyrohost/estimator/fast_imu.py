"""The IMU's prediction with the dynamics' linearisation (:func:`.imu_prediction.predict_imu`,
closed form) in one call of the model's compiled kernel (``gyrotensegrity._fastkernel.imu``).

The reference takes the sensor frame's derivatives by the complex step over the node positions
and velocities (24 perturbed states on the D-bar, batched in numpy); the kernel takes them in
forward mode (dual numbers) over the frame's twelve inputs, the two edge vectors of its nodes
and their rates, and chains them to the states, whose effect on those vectors is linear. Both
are exact to round-off; tests/estimator/test_fast_imu.py holds them equal. The mounting's
columns, where the mounting is a state, are added as the reference adds them. The three
measurements of a sample (:meth:`FastImu.measurements`, the ``fuse_imu_*`` modules' in one
kernel call) follow. Covered as :mod:`.fast_prediction`; elsewhere :func:`fast_imu` gives None.
"""

import numpy as np

from . import fuse_imu_accel, fuse_imu_angle, fuse_imu_rate
from .fast_prediction import kink_std
from .fusion import Measurement
from .imu_prediction import ImuPrediction, with_mounting


def fast_imu(ekf):
    """A :class:`FastImu` of the filter ``ekf`` where its prediction step is the compiled one
    (the same coverage), else None."""
    return None if ekf.fast_step is None else FastImu(ekf)


class FastImu:
    """:func:`.imu_prediction.predict_imu` in the compiled kernel, for one filter."""

    def __init__(self, ekf):
        self.ekf = ekf
        process = ekf.process
        self.dyn, self.kernel = process.dyn, process.dyn.kernel
        L, imu = ekf.layout, ekf.imu
        self.nd, self.alpha, self.nw = L.n_dynamic, L.n_strings, L.n_wheels
        rows = self.dyn.U_T.A[:, [imu.a, imu.b, imu.c]].T  # (3, m): the nodes' rows of U
        N_fix = self.dyn.N_fix[:, [imu.a, imu.b, imu.c]].T  # (3 nodes, 3 axes)
        # [servo lag, wheel slope, rest command, wheel accelerations, gravity, R_bs, rows, N_fix,
        # the mean kink's std]
        head = 2 + self.alpha + self.nw
        self._spec = np.concatenate([np.zeros(head), imu.gravity, imu.R_bs.ravel(), rows.ravel(),
                                     N_fix.ravel(), [kink_std(ekf.config)]])  # fmt: skip
        self._R_bs = slice(head + 3, head + 12)
        self._work = np.empty(self.kernel.imu_work(self.dyn._dims))
        self._columns = np.asarray(ekf.imu_columns, np.int64)

    def __call__(self, x, u) -> ImuPrediction:
        """The IMU's prediction at the filter state ``x`` (n,) under ``u``, as
        :func:`.imu_prediction.predict_imu` gives it."""
        ekf, p, spec = self.ekf, self.ekf.process, self._spec
        L = ekf.layout
        spec[0], spec[1] = ekf.config.servo_lag_s, p.wheel_acceleration_slope()
        a = 2 + self.alpha
        spec[2:a] = u[: self.alpha]
        spec[a : a + self.nw] = p.wheel_acceleration(x[None, L.omega], u)[0]
        R_bs, dR_bs = ekf.imu.mounting(x[L.mounting]) if L.n_mounting else (ekf.imu.R_bs, None)
        spec[self._R_bs] = R_bs.ravel()
        nd = self.nd
        f, A = np.empty(nd), np.empty((nd, nd))
        R, dR, om, dom = np.empty((3, 3)), np.empty((9, nd)), np.empty(3), np.empty((3, nd))
        force, dforce = np.empty(3), np.empty((3, nd))
        status = self.kernel.imu(
            self.dyn._consts, self.dyn._dims, spec, np.ascontiguousarray(x), f, A, R, dR, om, dom,
            force, dforce, self._work,
        )  # fmt: skip
        if status:
            self.dyn._singular(float("nan"), status - 1)
        pred = ImuPrediction(R, dR, om, dom, force, dforce, A, f)
        return pred if dR_bs is None else with_mounting(pred, R_bs, dR_bs)

    def constants(self):
        """The kernel's IMU constants, the sensor's axes in body axes fixed (no mounting
        state): gravity, R_bs, the nodes' rows of U, N_fix."""
        return self._spec[self._R_bs.start - 3 : -1]

    def measurement_spec(self):
        """The kernel's spec of the three measurements (``imu_measurements``'): the filter's lag
        behind the sample, the sensor's noise, the bias columns."""
        ekf, c = self.ekf, self.ekf.config
        L = ekf.layout
        accel_bias = L.accel_bias.start if L.n_accel_bias else -1
        return np.array([ekf.imu_lag_s, c.imu_time_std_s, c.imu_rate_std_rad_s,
                         c.imu_accel_std_m_s2, c.imu_angle_std_rad, fuse_imu_angle.FLOOR,
                         L.bias.start, accel_bias])  # fmt: skip

    def measurements(self, pred: ImuPrediction, omega_rad_s, accel_m_s2, euler_rad):
        """The rate, specific-force and attitude measurements of one IMU sample, as
        ``fuse_imu_rate``, ``fuse_imu_accel`` and ``fuse_imu_angle`` make them from ``pred``."""
        ekf = self.ekf
        n = ekf.layout.size
        spec = self.measurement_spec()
        z = np.concatenate([omega_rad_s, accel_m_s2, euler_rad]).astype(float)
        H, hx, z_out, R = np.empty((9, n)), np.empty(9), np.empty(9), np.empty((9, 9))
        fields = (pred.R_ws, pred.dR_ws, pred.omega, pred.d_omega, pred.specific_force,
                  pred.d_specific_force, pred.x_dot)  # fmt: skip
        fields = [np.ascontiguousarray(f, float) for f in fields]
        x = np.ascontiguousarray(ekf.x)
        self.kernel.imu_measurements(self._columns, spec, *fields, x, z, H, hx, z_out, R)
        sources = (fuse_imu_rate.SOURCE, fuse_imu_accel.SOURCE, fuse_imu_angle.SOURCE)
        return [
            Measurement(s, z_out[i : i + 3], hx[i : i + 3], H[i : i + 3], R[i : i + 3, i : i + 3])
            for s, i in zip(sources, (0, 3, 6), strict=True)
        ]
