"""An IMU sample's whole cycle in one call of the model's compiled kernel
(``gyrotensegrity._fastkernel.imu_cycle``).

The stage-by-stage fast path makes six kernel calls per IMU sample (the prediction step, the
state onto the bars, the IMU's prediction, its three measurements, their update, the posterior
onto the bars) and each costs less than the Python that builds its arguments and checks its
results. Here the last prediction step to the sample and everything after it are one call
with the same arithmetic (tests/estimator/test_fast_cycle.py holds the two paths equal); the
process noise other than the kinks' is still :meth:`.process_noise.ProcessNoise.noise`'s.
Every fusion is logged as the stages log it: innovation, variance, test ratio
(:func:`.fusion.judge`).

Where a stage refuses (the model singular, a value not finite, axes that are no rotation, a
Gram matrix or an innovation covariance not positive definite) the call changes nothing and
the filter takes the stages from the same state: they raise the filter's error, or fall back
to the reference, as they do without this module.

Covered: the configurations of :mod:`.fast_prediction` without the mounting as a state (its
three Jacobian columns are the stages' :func:`.imu_prediction.with_mounting`) and without the
parameters' errors (their part of the step is :mod:`.param_errors`').
"""

import numpy as np

from . import fuse_imu_accel, fuse_imu_angle, fuse_imu_rate
from .fusion import gate, judge
from .servo_motion import step_input

SOURCES = (fuse_imu_rate.SOURCE, fuse_imu_accel.SOURCE, fuse_imu_angle.SOURCE)


def fast_cycle(ekf, rotation_tolerance: float):
    """A :class:`FastCycle` of the filter ``ekf`` where it covers the configuration (module
    docstring), else None; ``rotation_tolerance`` as the filter's check of the IMU's axes."""
    covered = ekf.fast_imu is not None and not ekf.layout.n_mounting and ekf.params is None
    return FastCycle(ekf, rotation_tolerance) if covered else None


class FastCycle:
    """:meth:`~.ekf.TensegrityEKF.fuse_imu`'s last step and fusion in one kernel call."""

    def __init__(self, ekf, rotation_tolerance: float):
        self.ekf = ekf
        dyn = ekf.process.dyn
        self.kernel, self._model = dyn.kernel, (dyn._consts, dyn._dims)
        n, nd = ekf.layout.size, ekf.layout.n_dynamic
        gates = [gate(ekf.config.gate_probability, 3)] * 3
        # the kernel's spec: [step, IMU constants, measurements (the lag first), z, gates,
        # rotation tolerance, the manifold's rtol and iterations]; all but the step, the lag
        # and z fixed for the filter's life
        measurements = ekf.fast_imu.measurement_spec()
        self._spec = np.concatenate([np.zeros(ekf.fast_step.spec_size), ekf.fast_imu.constants(),
                                     measurements, np.zeros(9), gates,
                                     [rotation_tolerance, 1e-15, 8.0]])  # fmt: skip
        self._lag = len(self._spec) - 6 - 9 - len(measurements)
        self._bars = ekf.manifold.packed_bars
        self._columns = np.asarray(ekf.imu_columns, np.int64)
        self._no_A, self._no_Q = np.zeros((nd, nd)), np.zeros((0, 0))
        self._work = np.empty(self.kernel.cycle_work(dyn._dims, n))

    def __call__(self, dt: float, omega_rad_s, accel_m_s2, euler_rad):
        """Predict ``dt`` s (0: not at all) and fuse the IMU sample; its :class:`.fusion.
        Innovation` list, or None where a stage refused (the filter unchanged)."""
        ekf = self.ekf
        process, n = ekf.process, ekf.layout.size
        step, sp0 = ekf.fast_step.step_spec(step_input(ekf, dt), dt, ekf._A is not None)
        spec, z = self._spec, self._lag + 8
        spec[: len(step)] = step
        spec[self._lag] = ekf.imu_lag_s
        spec[z : z + 3] = omega_rad_s
        spec[z + 3 : z + 6] = accel_m_s2
        spec[z + 6 : z + 9] = euler_rad
        Q = process.noise(dt, None, ekf.x) if dt > 0.0 else self._no_Q
        A_in = self._no_A if ekf._A is None else ekf._A
        x, P, A, out = np.empty(n), np.empty((n, n)), np.empty(self._no_A.shape), np.empty(36)
        prior = np.ascontiguousarray(ekf.x), np.ascontiguousarray(ekf.P)
        if self.kernel.imu_cycle(*self._model, spec, self._columns, self._bars, *prior, A_in, Q,
                                 x, P, A, out, self._work):  # fmt: skip
            return None
        if dt > 0.0:
            process.setpoints_moved(sp0, dt)
            ekf.t += dt
            ekf.check_timeouts()
        ekf._A = A
        ekf.kf.x, ekf.kf.P = x.reshape(-1, 1), P
        y, S_diag, w, stats = out[:9], out[9:18], out[18:27], out[27:].reshape(3, 3)
        results = [
            judge(ekf, s, y[i : i + 3], S_diag[i : i + 3], w[i : i + 3], stats[j, 1], stats[j, 0])
            for j, (s, i) in enumerate(zip(SOURCES, (0, 3, 6), strict=True))
        ]
        for r in results:
            ekf.emit(r)
        return results
