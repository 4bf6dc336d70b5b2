"""One linearisation of everything an IMU sample measures, shared by the three IMU fusions.

A single batched complex-step evaluation of the dynamics over all dynamic states at the prior
gives the sensor axes, the angular rate, the specific force, and ``A = df/dx`` (kept for the
next prediction of the lean process model). With ``jacobian = "analytic"`` the dynamics'
part is in closed form (:meth:`.process_model.ProcessModel.closed_form`) and only the frame
(a function of the node positions and velocities alone) goes through the complex step. With
the mounting's error as a state (``layout.mounting``) the frame uses the estimated mounting and
the Jacobians get its three columns in closed form (:func:`with_mounting`).
"""

from dataclasses import dataclass, replace

import numpy as np

from . import complex_step


@dataclass(frozen=True)
class ImuPrediction:
    """Values and Jacobians at one estimate; the Jacobians' k columns are the dynamic states
    (``ekf.imu_columns``: then the mounting states, if any).

    R_ws (3, 3) and its Jacobian (9, k); omega (3,) rad/s and (3, k); specific_force (3,)
    m/s^2 and (3, k); A (n_dynamic, n_dynamic); x_dot (k,) the time derivative of those states
    (the dynamics'; the mounting's is 0).
    """

    R_ws: np.ndarray
    dR_ws: np.ndarray
    omega: np.ndarray
    d_omega: np.ndarray
    specific_force: np.ndarray
    d_specific_force: np.ndarray
    A: np.ndarray
    x_dot: np.ndarray


def predict_imu(ekf, x, u) -> ImuPrediction:
    """Linearise the IMU measurements (and the dynamics) at filter state ``x`` under ``u``."""
    L = ekf.layout
    if not L.n_mounting:
        return _predict(ekf, x, u, ekf.imu.R_bs)
    R_bs, dR_bs = ekf.imu.mounting(x[L.mounting])
    return with_mounting(_predict(ekf, x, u, R_bs), R_bs, dR_bs)


def _predict(ekf, x, u, R_bs) -> ImuPrediction:
    """:func:`predict_imu` over the dynamic states, the sensor axes ``R_bs`` in body axes."""
    if ekf.process.jac is not None:
        return _closed_form(ekf, x, u, R_bs)
    cols = ekf.dynamic_columns
    X = complex_step.perturbed(x[: len(cols)], cols)
    dx, N_ddot = ekf.process.derivative(X, u, with_node_accelerations=True)
    N, N_dot = ekf.batch_nodes(X)
    R_ws, omega = ekf.imu.frame(N, N_dot, R_bs)
    f = ekf.imu.specific_force(R_ws, N_ddot)
    K = X.shape[0]
    R, dR = complex_step.split(R_ws.reshape(K, 9))
    w, dw = complex_step.split(omega)
    fv, df = complex_step.split(f)
    x_dot, A = complex_step.split(dx)
    return ImuPrediction(R.reshape(3, 3), dR, w, dw, fv, df, A, x_dot)


def _closed_form(ekf, x, u, R_bs) -> ImuPrediction:
    """:func:`_predict` with the dynamics' Jacobian in closed form: the node accelerations'
    Jacobian is ``U`` times the reduced one; ``f = R^T a`` gives ``df = dR^T a + R^T da``."""
    nd, motion = ekf.layout.n_dynamic, ekf.motion_columns
    x_dot, A, _, J = ekf.process.closed_form(x, u)
    dyn, m = ekf.process.dyn, ekf.layout.m
    N_ddot = dyn.node_values(x_dot[ekf.layout.q_dot].reshape(3, m))  # (3, n)
    dN_ddot = dyn.node_values(J.T.reshape(nd, 3, m))  # (nd, 3, n)
    X = complex_step.perturbed(x[: len(motion)], motion)
    N, N_dot = ekf.batch_nodes(X)
    R_ws, omega = ekf.imu.frame(N, N_dot, R_bs)
    R, dR = _padded(*complex_step.split(R_ws.reshape(len(motion), 9)), nd)
    w, dw = _padded(*complex_step.split(omega), nd)
    imu = ekf.imu
    a = 0.5 * (N_ddot[:, imu.a] + N_ddot[:, imu.b]) - imu.gravity
    da = 0.5 * (dN_ddot[:, :, imu.a] + dN_ddot[:, :, imu.b]).T  # (3, nd)
    R = R.reshape(3, 3)
    df = R.T @ da + np.einsum("jik,j->ik", dR.reshape(3, 3, nd), a)
    return ImuPrediction(R, dR, w, dw, R.T @ a, df, A, x_dot)


def with_mounting(pred: ImuPrediction, R_bs, dR_bs) -> ImuPrediction:
    """``pred`` with three more Jacobian columns, by the mounting's roll, pitch and yaw error
    (``dR_bs`` (3, 3, 3) the derivatives of the sensor axes in body axes ``R_bs``): with
    ``R_ws = R_wb R_bs``, ``omega_s = R_bs^T omega_b`` and ``f = R_ws^T a``, the derivative by
    the k-th angle is ``R_wb dR_bs[k]``, ``dR_bs[k]^T omega_b`` and ``(R_wb dR_bs[k])^T a``."""
    R_wb = pred.R_ws @ R_bs.T
    omega_b = R_bs @ pred.omega
    a = pred.R_ws @ pred.specific_force
    dR_ws = R_wb @ dR_bs  # (3, 3, 3): k, then the matrix
    return replace(
        pred,
        dR_ws=np.hstack([pred.dR_ws, dR_ws.reshape(3, 9).T]),
        d_omega=np.hstack([pred.d_omega, np.einsum("kji,j->ik", dR_bs, omega_b)]),
        d_specific_force=np.hstack([pred.d_specific_force, np.einsum("kji,j->ik", dR_ws, a)]),
        x_dot=np.concatenate([pred.x_dot, np.zeros(3)]),
    )


def _padded(value, jacobian, nd):
    """A value and its Jacobian over the motion columns, the latter padded to nd columns."""
    out = np.zeros((jacobian.shape[0], nd))
    out[:, : jacobian.shape[1]] = jacobian
    return value, out


def at_sample_time(ekf, pred: ImuPrediction, J, h):
    """The prediction ``h`` (k,) taken back to the sample's time when the filter is
    ``ekf.imu_lag_s`` ahead of it: ``h - lag dh/dt``, ``dh/dt = J x_dot`` (J over
    ``ekf.imu_columns``)."""
    return h - ekf.imu_lag_s * (J @ pred.x_dot)


def timing_noise(ekf, pred: ImuPrediction, J, std):
    """Measurement covariance (k, k) of white noise ``std`` per component plus the IMU's
    sample-time uncertainty (``imu_time_std_s``): a sample taken ``dt`` off the time it is
    fused at reads ``h + dt dh/dt``, ``dh/dt = J x_dot`` (J over ``ekf.imu_columns``)."""
    h_dot = J @ pred.x_dot
    return np.eye(len(h_dot)) * std**2 + ekf.config.imu_time_std_s**2 * np.outer(h_dot, h_dot)


def full_jacobian(ekf, J):
    """A Jacobian over ``ekf.imu_columns``, padded with zero columns for the rest: (k, n)."""
    H = np.zeros((J.shape[0], ekf.layout.size))
    H[:, ekf.imu_columns] = J
    return H
