"""The lean prediction step with its covariance in one call of the model's compiled kernel.

The reference is :meth:`.process_model.ProcessModel.step` (``process_method = "lean"``) followed
by filterpy's ``F P F^T``: Python around small numpy operations, each costing more than the
arithmetic it does. ``gyrotensegrity._fastkernel.lean_step`` does the same arithmetic (the RK4
substeps through the kernel's closed-form Jacobian at every stage, the first one the IMU
prediction's where it made one, ``F`` chained through them, ``F P F^T`` and the rest-length
kinks' noise, which needs this ``F`` and ``P``) in one call; the rest of the
process noise stays with :class:`.process_noise.ProcessNoise` (cached for the repeated step).
tests/estimator/test_fast_prediction.py holds the two equal to round-off.

Covered: the lean model with the closed-form Jacobian, either string kink (the mean one's smooth
force and its Jacobian through the pulling rest lengths in the kernel too), a model that omits
no term (the omitted-term check looks at every stage's spins), the paper's wheel reaction
(``wheel_reaction = "lost"``: the kernel has no turn of the whole structure) and the kernel
built; elsewhere :func:`fast_prediction` gives None and the filter takes the reference path.
"""

import numpy as np


def fast_prediction(process, n: int):
    """A :class:`FastPrediction` for the process model ``process`` and an ``n``-entry filter
    state, or None where it does not cover the configuration (module docstring)."""
    c, dyn = process.config, process.dyn
    jac = process.jac
    covered = (
        c.process_method == "lean"
        and jac is not None
        and jac.kernel is not None
        and not process.model.omitted
        and process.reaction is None
    )
    return FastPrediction(process, n) if covered and dyn.kernel is not None else None


def kink_std(config) -> float:
    """The rest-length jitter's std per step, m, that the mean kink smooths the strings' force
    over (:meth:`.process_model.ProcessModel.mean_force_rest`); 0 for the sharp kink."""
    if config.kink_model != "mean":
        return 0.0
    return float(np.sqrt(config.rest_jitter_psd_m2_s / config.process_dt_s))


class FastPrediction:
    """The lean step of ``process`` (a :class:`.process_model.ProcessModel`) in the kernel.

    Parameters
    ----------
    process : ProcessModel
    n : int
        Entries of the filter state (the dynamic ones first; the rest held).
    """

    def __init__(self, process, n: int):
        self.process = process
        dyn = process.dyn
        self.dyn, self.kernel = dyn, dyn.kernel
        L = process.layout
        self.n, self.nd, self.alpha, self.nw = n, L.n_dynamic, L.n_strings, L.n_wheels
        # [dt, servo lag, wheel lag, wheel accel, follow, have A, rest command, wheel
        # accelerations, setpoints, commands, jitter density, mean kink's std, filter step,
        # RK4 substeps] (the kernel's StepSpec)
        c = process.config
        self.spec_size = 10 + self.alpha + 3 * self.nw
        self._spec = np.zeros(self.spec_size)
        self._spec[-4:-1] = c.rest_jitter_psd_m2_s, kink_std(c), c.process_dt_s
        self._work = np.empty(self.kernel.lean_work(dyn._dims, n))
        self._no_A = np.zeros((self.nd, self.nd))

    def step_spec(self, u, dt: float, have_A: bool):
        """The kernel's spec of a step of ``dt`` s under ``u`` (a buffer reused by the next
        call) and the wheels' setpoints at its start."""
        p, c, spec = self.process, self.process.config, self._spec
        sp0 = p.wheel_setpoint_rad_s
        follow = p.wheel_target_rad_s is not None and c.wheel_lag_s != 0.0
        spec[:6] = dt, c.servo_lag_s, c.wheel_lag_s, c.wheel_accel_rad_s2, follow, have_A
        spec[-1] = p.substeps(dt)
        a, nw = 6 + self.alpha, self.nw
        spec[6:a] = u[: self.alpha]
        if follow:
            spec[a + nw : a + 2 * nw] = sp0
            spec[a + 2 * nw : a + 3 * nw] = p.wheel_command_rad_s
        else:
            spec[a : a + nw] = self.dyn.wheel_acceleration(u)  # the model's, as the step's
        return spec, sp0

    def __call__(self, x, P, u, dt, A=None):
        """The state (n,) and covariance (n, n) ``dt`` s on, with the process noise of the
        strings' kinks (:meth:`.process_noise.ProcessNoise.kink_noise`) but no other, and
        the step's Jacobian ``F`` (n_dynamic, n_dynamic) over the dynamic states (the identity
        beyond them), from ``x`` (n,) and ``P`` (n, n) under the input ``u``; ``A`` as
        :meth:`.process_model.ProcessModel.step`. Moves the wheels' setpoints on as the step
        does."""
        p = self.process
        spec, sp0 = self.step_spec(u, dt, A is not None)
        x_out, P_out, F = np.empty(self.n), np.empty((self.n, self.n)), np.empty((self.nd,) * 2)
        A = self._no_A if A is None else A
        status = self.kernel.lean_step(
            self.dyn._consts,
            self.dyn._dims,
            spec,
            np.ascontiguousarray(x),
            np.ascontiguousarray(P),
            np.ascontiguousarray(A),
            x_out,
            P_out,
            F,
            self._work,
        )
        if status:
            self.dyn._singular(float("nan"), status - 1)
        p.setpoints_moved(sp0, dt)
        return x_out, P_out, F
