"""The estimator's health over a run: NIS per source, gate rejections, and on the simulated rig
the NEES against its truth; a diverged estimate fails the run.

:class:`NisTally` counts every fusion attempt (the run's innovation writer feeds it);
:class:`TruthScore` scores each estimate against the simulated rig's truth interpolated to its
time (:func:`gyrohost.estimator.consistency.observed_nees`: node coordinates on the
constraint manifold, wheel speeds and rest lengths). The summary's ``estimator`` table
(:func:`health`) gives each NIS mean with the two-sided 95 % chi-square bounds of a mean over
that many samples (a guide: a consistent filter's innovations are white, a real loop's
nearly so) and the NEES mean with the share of its samples inside their own 95 % bounds: the
estimate's errors are correlated from step to step, so the bounds of a mean over the samples
of one run would be far too narrow (those of a mean over runs: ``gyrotens sil --runs N``). It
says whether the estimate diverged; the run adds whether it was ``required`` to hold
(:func:`fails_run`).
"""

import bisect
from collections import deque

import numpy as np

from gyrohost.estimator.consistency import average_bounds, observed_nees, state_of_truth

DIVERGED_NODE_ERROR_M = 0.05
"""RMS node coordinate error (over the last :data:`RECENT` truth samples) above which the
estimate has diverged: three times the largest seen on a rig whose truth lagged its devices by
0.25 s (17.7 mm), a quarter of the D-bar's half diagonal (0.22 m)."""
DIVERGED_REJECTED_IN_A_ROW = 50
"""Gate rejections in a row of one source after which the estimate has diverged (0.5 s of IMU)."""
REJECTED_WARNING_S = 0.25
"""A source the gate refused without a break for longer than this, s, is warned about: half the
silence after which a device ends the run (``[run] imu_silence_s``, 0.5 s), since the estimate
ran on prediction alone for it as long as for a device half-way to that fault. Divergence
(:data:`DIVERGED_REJECTED_IN_A_ROW`) is judged at the end only; this is any stretch."""
RECENT = 50
MAX_TRUTH_GAP_S = 0.025
"""Truth samples further apart than this (the truth stalled: a loaded machine) bracket no
estimate; the simulated rig sends every 5 ms step's."""
TRUTH_KEPT = 512
"""Truth samples kept for estimates still to come (2.5 s of 5 ms steps: an estimate lags its
loop by some tens of ms)."""


def _mean_row(total: float, samples: int, dof: int) -> dict:
    lo, hi = average_bounds(dof, samples) if samples else (float("nan"),) * 2
    mean = total / samples if samples else float("nan")
    return {"mean": mean, "dof": dof, "samples": samples, "bounds95": [lo, hi]}


def nis_row(nis, dof: int) -> dict:
    """The summary's row of a source's NIS values ``nis`` (k,) of ``dof`` each: mean, dof,
    samples and the 95 % bounds of a mean over that many samples (as :class:`NisTally`)."""
    return _mean_row(float(np.sum(nis)), len(nis), dof)


class NisTally:
    """Fusion attempts per source: samples, rejected, rejected in a row, NIS sum."""

    def __init__(self):
        self.sources: dict = {}

    def add(self, inn) -> None:
        """Count one :class:`~gyrohost.estimator.fusion.Innovation`."""
        s = self.sources.setdefault(
            inn.source,
            {"samples": 0, "rejected": 0, "in_a_row": 0, "nis": 0.0, "dof": len(inn.innovation),
             "since_s": None, "longest_s": 0.0, "longest_at_s": None},
        )  # fmt: skip
        s["samples"] += 1
        s["nis"] += inn.nis
        s["rejected"] += not inn.accepted
        s["in_a_row"] = 0 if inn.accepted else s["in_a_row"] + 1
        self._stretch(s, inn)

    @staticmethod
    def _stretch(s: dict, inn) -> None:
        """The longest stretch of rejections: from the first rejected sample's time to the
        next accepted one's (to the last rejected one's while it lasts)."""
        if not inn.accepted and s["since_s"] is None:
            s["since_s"] = inn.t_s
        if s["since_s"] is not None and inn.t_s - s["since_s"] > s["longest_s"]:
            s["longest_s"], s["longest_at_s"] = inn.t_s - s["since_s"], s["since_s"]
        if inn.accepted:
            s["since_s"] = None

    def table(self) -> dict:
        """Source -> mean NIS with its bounds, samples, rejected, most recent rejections in a
        row."""
        out = {}
        for source, s in self.sources.items():
            row = _mean_row(s["nis"], s["samples"], s["dof"])
            out[source] = {**row, "rejected": s["rejected"], "rejected_in_a_row": s["in_a_row"],
                           "longest_rejected_s": s["longest_s"],
                           "longest_rejected_from_s": s["longest_at_s"]}  # fmt: skip
        return out


class TruthScore:
    """NEES and node error of the estimate against the simulated rig's truth at the estimate's
    own time.

    Each estimate kept (:meth:`estimate`) is scored once two truth samples bracket its time, at
    the truth interpolated linearly between them: node positions, wheel speeds and rest lengths
    (over a 5 ms truth step the chord of a turn at 2 rad/s is 2 um from the arc on the D-bar,
    far inside its estimate's spread; the rest lengths and a speed-driven truth's spins are
    what the truth held between its steps, so that between every step's samples they are
    exact). Scoring an estimate against the truth sample nearest in
    time instead compares two times up to half a truth step apart, and in the paper's last turn
    (2 rad/s) 5 ms is half a degree, ten times the estimate's spread: the NEES then measures the
    scoring, not the estimate. Estimates and truth samples come in time order, either first.

    Parameters
    ----------
    ekf : TensegrityEKF
    """

    def __init__(self, ekf):
        self.ekf = ekf
        self.waiting: deque = deque()  # (t_s, x, P) estimates not yet scored
        self.truths: list = []  # (t_s, N, omega, rest), from the one before the next estimate
        self.nees: list[float] = []
        self.node_error_m: list[float] = []
        self.dof = 0

    def estimate(self) -> None:
        """Keep the estimate as it stands now, to be scored (once at a time: a second call
        before the filter moved on is ignored)."""
        e = self.ekf
        if not self.waiting or e.t > self.waiting[-1][0]:
            self.waiting.append((e.t, e.x.copy(), e.P.copy()))
            self._score_waiting()

    def truth(self, t_s: float, N, omega_rad_s, rest_m) -> None:
        """Take a truth sample of the simulated rig.

        Parameters
        ----------
        t_s : float, s, host time of the sample
        N : ndarray, shape (3, n_nodes), m, every node of the structure
        omega_rad_s : ndarray, shape (n_w,); rest_m : ndarray, shape (n_s,)
        """
        if self.truths and t_s <= self.truths[-1][0]:
            return  # not after the last: no interval to interpolate over
        sample = (N, omega_rad_s, rest_m)
        self.truths.append((float(t_s), *(np.array(v, float) for v in sample)))
        self._score_waiting()

    def _score_waiting(self) -> None:
        """Score the waiting estimates that truth samples now bracket (those before every kept
        truth sample, or within a gap of the truth longer than :data:`MAX_TRUTH_GAP_S`, go
        unscored)."""
        times = [t for t, *_ in self.truths]
        while self.waiting and times and self.waiting[0][0] <= times[-1]:
            t, x, P = self.waiting.popleft()
            k = bisect.bisect_left(times, t)
            if times[k] == t:
                self._score(x, P, *self.truths[k][1:])
            elif k > 0 and times[k] - times[k - 1] <= MAX_TRUTH_GAP_S:
                (t_a, *a), (t_b, *b) = self.truths[k - 1], self.truths[k]
                w = (t - t_a) / (t_b - t_a)
                self._score(x, P, *(u + w * (v - u) for u, v in zip(a, b, strict=True)))
            # later estimates come no earlier: the samples before this one's interval go
            del self.truths[: max(k - 1, 0)], times[: max(k - 1, 0)]
        del self.truths[: max(len(self.truths) - TRUTH_KEPT, 0)]

    def _score(self, x, P, N, omega_rad_s, rest_m) -> None:
        x_true = state_of_truth(self.ekf, x, N, omega_rad_s, rest_m)
        value, self.dof = observed_nees(self.ekf, x, P, x_true)
        self.nees.append(value)
        q = self.ekf.layout.q
        self.node_error_m.append(float(np.sqrt(np.mean((x[q] - x_true[q]) ** 2))))

    def table(self) -> dict:
        """NEES mean, the share of its samples inside their own 95 % bounds (``inside``,
        ``sample_bounds95``), node error RMS over the run and over the last samples."""
        err = np.array(self.node_error_m)
        nees = np.array(self.nees)
        lo, hi = average_bounds(self.dof, 1)
        out = {
            "mean": float(np.mean(nees)) if nees.size else float("nan"),
            "dof": self.dof,
            "samples": int(nees.size),
            "inside": float(np.mean((nees >= lo) & (nees <= hi))) if nees.size else float("nan"),
            "sample_bounds95": [float(lo), float(hi)],
        }
        out["node_error_rms_m"] = float(np.sqrt(np.mean(err**2))) if err.size else float("nan")
        out["node_error_recent_rms_m"] = (
            float(np.sqrt(np.mean(err[-RECENT:] ** 2))) if err.size else float("nan")
        )
        return out


def health(nis: NisTally | None, truth: TruthScore | None) -> dict:
    """The summary's ``estimator`` table: ``nis`` per source, ``nees`` (simulated rig only),
    ``diverged`` and why."""
    out: dict = {"nis": nis.table() if nis is not None else {}}
    why = [
        f"{source}: last {row['rejected_in_a_row']} samples rejected by the gate"
        for source, row in out["nis"].items()
        if row["rejected_in_a_row"] >= DIVERGED_REJECTED_IN_A_ROW
    ]
    if truth is not None and truth.nees:
        out["nees"] = truth.table()
        recent = out["nees"]["node_error_recent_rms_m"]
        if recent > DIVERGED_NODE_ERROR_M:
            why.append(
                f"node error {1e3 * recent:.1f} mm RMS over the last truth samples "
                f"(limit {1e3 * DIVERGED_NODE_ERROR_M:g} mm)"
            )
    out["diverged"] = bool(why)
    out["why"] = "; ".join(why)
    return out


def rejection_warnings(table: dict) -> list[str]:
    """The sources of a :func:`health` table the gate refused for longer than
    :data:`REJECTED_WARNING_S` at a stretch, one line each."""
    return [
        f"estimator: the gate refused every {source} sample for {row['longest_rejected_s']:.2f} s "
        f"from t = {row['longest_rejected_from_s']:.2f} s (more than {REJECTED_WARNING_S:g} s): "
        "the estimate ran on prediction for it"
        for source, row in table.get("nis", {}).items()
        if row.get("longest_rejected_s", 0.0) > REJECTED_WARNING_S
    ]


def fails_run(table: dict) -> bool:
    """Whether the summary's ``estimator`` table fails the run: diverged where the run required
    the estimate to hold (every run but an identification run, whose scene is the one still to
    be identified)."""
    return bool(table.get("diverged")) and table.get("required", True)


def health_lines(table: dict) -> list[str]:
    """Printable lines of a :func:`health` table."""

    def row(name, r):
        lo, hi = r["bounds95"]
        return (
            f"{name} {r['mean']:.2f} (dof {r['dof']}, 95 % [{lo:.2f}, {hi:.2f}], n {r['samples']})"
        )

    lines = []
    if "nees" in table:
        n = table["nees"]
        lo, hi = n["sample_bounds95"]
        lines.append(
            f"estimator vs truth: NEES {n['mean']:.2f} (dof {n['dof']}), "
            f"{100 * n['inside']:.1f} % of {n['samples']} samples inside their 95 % bounds "
            f"[{lo:.2f}, {hi:.2f}] (a consistent filter: about 95 %; the bounds of the mean "
            f"need several runs: gyrotens sil); node error RMS "
            f"{1e3 * n['node_error_rms_m']:.2f} mm"
        )
    nis = [f"{row(s, r)}, {r['rejected']} rejected" for s, r in table["nis"].items()]
    if nis:
        lines.append("estimator NIS: " + "; ".join(nis))
    if table.get("lag_s"):
        lag = {k: 1e3 * v for k, v in table["lag_s"].items()}
        lines.append(
            f"estimator behind the loop: median {lag['median']:.1f} ms, p99 {lag['p99']:.1f} ms, "
            f"max {lag['max']:.1f} ms"
        )
    if table.get("not_fused_behind"):
        lines.append(
            f"estimator: {table['not_fused_behind']} samples not fused, to catch up with real "
            "time (the host was too slow)"
        )
    if fails_run(table):
        lines.append(f"estimator DIVERGED: {table['why']}")
    elif table.get("diverged"):
        lines.append(
            f"estimator diverged: {table['why']} (expected on an identification run: the scene "
            "is the one still to be identified; the log is what gyrotens identify fits)"
        )
    return lines
