"""Diagnostics of a state: constraint errors, energy, momentum (bars, wheels, point masses).

All functions take node matrices, so they apply to run files and to live states alike.
"""

import numpy as np


def bar_length_error(model, N):
    """|b_i| - l_i, shape (beta,), m."""
    st = model.structure
    return np.linalg.norm(N[:, st.bar_end] - N[:, st.bar_start], axis=0) - model.l


def joint_error(model, N):
    """Column norms of N P - D (Eq. 60), shape (c,), m."""
    st = model.structure
    return np.linalg.norm(np.asarray(model.P_T @ N.T).T - st.D, axis=0)


def wheel_speeds_per_bar(model, omega_w):
    """Spin of each bar's wheel, shape (beta,), rad/s (0 where a bar has no wheel)."""
    out = np.zeros(model.beta)
    out[model.wheel_bars] = omega_w
    return out


def energy(model, N, N_dot, omega_w, rest_length):
    """Kinetic, elastic and external-force potential energy, J (a dict; 'total' their sum).

    Kinetic energy of bar i: m_t |r_dot|^2 / 2 + J_t |b_dot|^2 / 2 + J_a l^2 omega_w^2 / 2.
    """
    st = model.structure
    B_dot = N_dot[:, st.bar_end] - N_dot[:, st.bar_start]
    R_dot = 0.5 * (N_dot[:, st.bar_end] + N_dot[:, st.bar_start])
    w = wheel_speeds_per_bar(model, omega_w)
    kinetic = 0.5 * (
        np.sum(model.m_t * np.sum(R_dot**2, axis=0))
        + np.sum(model.J_t * np.sum(B_dot**2, axis=0))
        + np.sum(model.J_a * model.l**2 * w**2)
        + np.sum(model.m_node * np.sum(N_dot**2, axis=0))
    )
    s = np.linalg.norm(N[:, st.string_end] - N[:, st.string_start], axis=0)
    stretch = np.maximum(s - rest_length, 0.0)
    elastic = 0.5 * np.sum(model.k_s * stretch**2)
    external = -np.sum(model.W * N)
    return {
        "kinetic": kinetic,
        "elastic": elastic,
        "external": external,
        "total": kinetic + elastic + external,
    }


def angular_momentum_parts(model, N, N_dot, omega_w):
    """Each body's angular momentum about the origin, shape (3, beta + n), kg m^2/s.

    Columns: one per bar (translation of its centre, Eq. 16 rotation and its wheel's spin), then
    one per node (its point mass; zero columns where there is none).
    """
    st = model.structure
    B = N[:, st.bar_end] - N[:, st.bar_start]
    B_dot = N_dot[:, st.bar_end] - N_dot[:, st.bar_start]
    R = 0.5 * (N[:, st.bar_end] + N[:, st.bar_start])
    R_dot = 0.5 * (N_dot[:, st.bar_end] + N_dot[:, st.bar_start])
    w = wheel_speeds_per_bar(model, omega_w)
    h = model.m_t * np.cross(R, R_dot, axis=0) + model.J_t * np.cross(B, B_dot, axis=0)
    h = h + model.J_a * model.l * w * B
    return np.hstack([h, np.cross(N, N_dot, axis=0) * model.m_node])


def angular_momentum(model, N, N_dot, omega_w):
    """Total angular momentum about the origin, shape (3,), kg m^2/s (Eq. 16 plus translation)."""
    return np.sum(angular_momentum_parts(model, N, N_dot, omega_w), axis=1)


def momentum_scale(model, N, N_dot, omega_w):
    """Sum of the bodies' angular momentum magnitudes, kg m^2/s: the scale for relative drift.

    Unlike the total it does not vanish when the parts cancel (a structure whose wheel momenta
    and motions sum to zero), so a drift relative to it stays meaningful there.
    """
    return float(np.sum(np.linalg.norm(angular_momentum_parts(model, N, N_dot, omega_w), axis=0)))


def highest_frequency(model):
    """An upper estimate of the fastest motion of the model, for step-size checks.

    Strings: ``sqrt(k (c_a + c_b))`` with ``c`` the node compliances ``diag(M_s^-1)`` (1/kg)
    of the string's end nodes; wheels: the nutation rate ``J_3 |omega_w| / (J_t l^2)`` of a
    free bar at the largest spin the scene states.

    Returns
    -------
    omega : float, rad/s
    member : str
        The string or bar that sets it ("" when the model has neither).
    """
    st = model.structure
    best, member = 0.0, ""
    if model.alpha:
        compliance = model.M_s_inv.diagonal()
        c = compliance[st.string_start] + compliance[st.string_end]
        w = np.sqrt(model.k_s * c)
        i = int(np.argmax(w))
        best, member = float(w[i]), model.scene.strings[i].name
    for k, i in enumerate(model.wheel_bars):
        spin = abs(model.spin0[k])
        if model.wheel_modes[k] == "speed":
            spin = max(spin, float(np.max(np.abs(model.wheel_schedules[k].value))))
        w = model.J3[i] * spin / (model.J_t[i] * model.l[i] ** 2)
        if w > best:
            best, member = float(w), model.scene.bars[i].name
    return best, member
