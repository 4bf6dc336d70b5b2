"""Counts and timing of a simulated rig's run (its rates and truth-timing report)."""

import math
from dataclasses import dataclass

LATE_SHARE_MAX = 0.1
"""Share of the truth's steps that may be late (more than a step behind wall time) for a run to
count as real time: beyond, the logged streams' stamps and the physics disagree by tens of ms
and vary, which an identification reads as a mounting or an inertia
(reports/identification-history.md)."""


@dataclass(frozen=True)
class RigStats:
    """Counts and timing of a rig run, for the rates report.

    Attributes
    ----------
    elapsed_s : float, s
        Rig time since start (wall time on the real clock).
    imu_samples, telemetry_frames, servo_packets : int
        IMU samples sent (3 frames each), wheel-board TELEMETRY frames sent, instruction
        packets the servo bus received.
    truth_steps, late_steps : int
    truth_dt_s, step_wall_s, max_lag_s, slipped_s : float, s
        Truth step, wall time spent stepping the truth, largest lateness of a step, and how far
        the truth fell behind wall time in total beyond ``MAX_LAG_S`` (real clock).
    cpu_s : float, s
        CPU time of this process since start (all threads).
    """

    elapsed_s: float
    imu_samples: int
    telemetry_frames: int
    servo_packets: int
    truth_steps: int
    late_steps: int
    truth_dt_s: float
    step_wall_s: float
    max_lag_s: float
    slipped_s: float
    cpu_s: float

    def rate(self, count: int) -> float:
        """``count`` per second of rig time."""
        return count / self.elapsed_s if self.elapsed_s > 0 else 0.0

    @property
    def real_time_factor(self) -> float:
        """Simulated seconds the truth advances per wall second of stepping."""
        sim_s = self.truth_steps * self.truth_dt_s
        return sim_s / self.step_wall_s if self.step_wall_s > 0 else math.inf

    def rates_line(self) -> str:
        """One line: measured rates per device."""
        return (
            f"rates: imu {self.rate(self.imu_samples):.1f} samples/s "
            f"({3 * self.rate(self.imu_samples):.1f} frames/s), "
            f"wheels {self.rate(self.telemetry_frames):.1f} telemetry frames/s, "
            f"servos {self.rate(self.servo_packets):.1f} packets/s"
        )

    def real_time(self) -> dict:
        """Whether the truth kept real time (:data:`LATE_SHARE_MAX`, no slip) and the figures
        that say so: ``kept``, ``late_share``, ``max_lag_s``, ``slipped_s``."""
        late = self.late_steps / max(self.truth_steps, 1)
        return {
            "kept": late <= LATE_SHARE_MAX and self.slipped_s == 0.0,
            "late_share": late,
            "max_lag_s": self.max_lag_s,
            "slipped_s": self.slipped_s,
        }

    def truth_line(self) -> str:
        """One line: truth step timing."""
        per_step_ms = 1e3 * self.step_wall_s / max(self.truth_steps, 1)
        return (
            f"truth: {self.truth_steps} steps of {1e3 * self.truth_dt_s:g} ms, "
            f"{per_step_ms:.2f} ms wall per step, real-time factor {self.real_time_factor:.1f}, "
            f"{self.late_steps} late steps (max lag {1e3 * self.max_lag_s:.1f} ms), "
            f"slipped {self.slipped_s:.2f} s; process CPU {100 * self.rate(self.cpu_s):.0f} %"
        )
