"""The wound strings' rest lengths between the servos' reports: the host's commands through a
servo response fitted to the reports.

The run reads the servos at 25 Hz (docs/run.md). A fast pull's corners, rounded by the servo's
response, fall between two reads, and straight lines between the reads cut them: the model
then sees a smoother pull than the rig made, and the fit takes less string damping for it
(reports/identification-history.md, "The servos' reports"). The commands come every tick. Put
through a delay and a first-order lag fitted to the reports (least squares on a grid), they give the
shape between the reads; the reports' remaining difference, interpolated, gives the level (a zero
offset, a load's sag: what the response does not model).
"""

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from gyrohost.estimator.servo_motion import lagged

GRID_S = 1e-3
"""Time step of the rendered lengths, s (each of the model's steps takes their mean over it)."""
DELAYS_S = np.arange(-0.02, 0.1 + 1e-9, 1e-3)
"""Delays tried, s: from a command's stamp to the servo starting towards it, as the reports'
stamps see it (they are taken on another thread than the commands': a few ms either way)."""
LAGS_S = np.concatenate([[0.0], np.geomspace(1e-3, 0.2, 48)])
"""First-order lags tried, s (0: the servo at its goal at once)."""


@dataclass(frozen=True)
class ServoResponse:
    """The servos' response to their commands, as fitted to their reports.

    Attributes
    ----------
    delay_s, lag_s : float, s
    rms_m : float, m
        Reports less the response at the reports' times, RMS over every servo.
    """

    delay_s: float
    lag_s: float
    rms_m: float


def fit_response(t_rep_s, rep_m, t_cmd_s, cmd_m, speed_m_s=np.inf) -> ServoResponse:
    """The delay and lag whose response to the commands (shapes (kc,), (kc, n)) is closest to
    the reports (shapes (kr,), (kr, n)) in the least-squares sense, over the reports the
    commands precede: the best of the grid :data:`DELAYS_S` x :data:`LAGS_S`, refined
    (Nelder-Mead; the grid's lags are 12 % apart, a ramp's corners need closer). The servos
    close their error at most at ``speed_m_s`` (m/s)."""
    t = _grid(t_rep_s, t_cmd_s)
    use = t_rep_s >= t_cmd_s[0] + DELAYS_S[-1]

    def mean_square(delay_s, y):
        at = t_rep_s[use] - delay_s
        err = np.column_stack([np.interp(at, t, v) for v in y.T]) - rep_m[use]
        return float(np.mean(err**2))

    grid = [
        (mean_square(d, y), d, lag_s)
        for lag_s in LAGS_S
        for y in [lagged(t_cmd_s, cmd_m, t, lag_s, speed_m_s)]
        for d in DELAYS_S
    ]
    _, delay0, lag0 = min(grid)
    sol = minimize(
        lambda p: mean_square(p[0], lagged(t_cmd_s, cmd_m, t, max(p[1], 0.0), speed_m_s)),
        [delay0, lag0],
        method="Nelder-Mead",
        options={"xatol": 1e-5, "fatol": 1e-14, "initial_simplex": _simplex(delay0, lag0)},
    )
    delay_s = float(np.clip(sol.x[0], DELAYS_S[0], DELAYS_S[-1]))
    lag_s = max(float(sol.x[1]), 0.0)
    rms = np.sqrt(mean_square(delay_s, lagged(t_cmd_s, cmd_m, t, lag_s, speed_m_s)))
    return ServoResponse(delay_s, lag_s, float(rms))


def _simplex(delay_s: float, lag_s: float) -> np.ndarray:
    step = max(0.12 * lag_s, 1e-3)
    return np.array([[delay_s, lag_s], [delay_s + 1e-3, lag_s], [delay_s, lag_s + step]])


def rendered(
    t_rep_s, rep_m, t_cmd_s, cmd_m, speed_m_s=np.inf
) -> tuple[np.ndarray, np.ndarray, ServoResponse]:
    """The rest lengths on a :data:`GRID_S` grid: the commands through the fitted
    :class:`ServoResponse` (at most at ``speed_m_s``), plus the reports' difference from it
    interpolated between them.

    Returns
    -------
    t_s : ndarray, shape (k,), s
    lengths_m : ndarray, shape (k, n), m
    response : ServoResponse
    """
    response = fit_response(t_rep_s, rep_m, t_cmd_s, cmd_m, speed_m_s)
    t = _grid(t_rep_s, t_cmd_s)
    y = lagged(t_cmd_s, cmd_m, t, response.lag_s, speed_m_s)
    shifted = [np.interp(t - response.delay_s, t, v) for v in y.T]
    at_reports = [np.interp(t_rep_s - response.delay_s, t, v) for v in y.T]
    lengths = np.column_stack(
        [
            s + np.interp(t, t_rep_s, r - a)
            for s, r, a in zip(shifted, rep_m.T, at_reports, strict=True)
        ]
    )
    return t, lengths, response


def fitted_response(recs) -> ServoResponse | None:
    """The servos' response fitted to the reads of the first of the recordings ``recs`` whose
    strings were rendered by it (None: none was)."""
    return next((r.servo_response for r in recs if getattr(r, "servo_response", None)), None)


def _grid(t_rep_s, t_cmd_s) -> np.ndarray:
    t0 = min(t_rep_s[0], t_cmd_s[0])
    t1 = max(t_rep_s[-1], t_cmd_s[-1])
    return t0 + GRID_S * np.arange(int(np.ceil((t1 - t0) / GRID_S)) + 1)
