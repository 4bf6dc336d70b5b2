"""Fusing a live run's samples in the order they were taken, not the order they came.

The IMU's samples reach the host ``imu_latency_s`` and more after they were taken; the wheel
board's and the servos' come sooner. Fused as they come, a wheel sample moves the filter past
the IMU samples still on their way, and those are then fused out of order, compared with the
prediction taken back along the dynamics (``h - lag dh/dt``; :meth:`.ekf.TensegrityEKF.
fuse_imu`): on the simulated rig nine IMU samples in ten, where a replay of the same log, which
merges the streams by their times, fuses them in order. The live estimate then scored worse than
its replay (NEES 36 against 21 on one run).

:class:`FusionHorizon` holds every sample until the IMU has delivered one taken no earlier, then
fuses the held ones in time order, as a replay does (the delayed fusion horizon of PX4's ekf2,
here as long as the IMU's own delay). The IMU's samples come in the order they were taken, so
nothing taken earlier than the newest of them can still be on its way from the IMU. While the
IMU is silent longer than ``max_age_s``, nothing waits for it: every held sample is fused and
the filter predicted to the tick, so that the sources' time-outs still fire.

Silence is counted from the newest IMU sample's stamp (when it came), not from when it was
taken: counted from the latter, an IMU whose latency is within ``max_age_s`` of the loop's
period seemed silent at most ticks, each tick moved the filter past the samples on their way,
and at 20 ms latency seven IMU samples in ten were fused out of order.

Commands (``set_input``) go straight to the filter, which queues them by their stamps.
"""

import heapq
import itertools
import math

from .config import imu_taken_s

FUSIONS = ("fuse_imu", "fuse_wheels", "fuse_servos")
"""The filter's calls that fuse a sample (first argument: its time stamp, s)."""


class FusionHorizon:
    """The samples of a live run in time order into the filter ``ekf``.

    Parameters
    ----------
    ekf : TensegrityEKF
    max_age_s : float, s
        An IMU silent this long holds nothing back; the tick predicts the filter to its time.
    """

    def __init__(self, ekf, max_age_s: float):
        self.ekf, self.max_age_s = ekf, float(max_age_s)
        self._held: list = []  # (time taken, arrival order, call, arguments)
        self._order = itertools.count()
        self.imu_s = -math.inf  # the newest IMU sample's time taken, s
        self.imu_stamp_s = -math.inf  # and its stamp, s

    def sample(self, kind: str, args) -> None:
        """Hold one sample (``kind`` one of :data:`FUSIONS`, ``args`` its arguments), then fuse
        whatever the IMU has caught up with."""
        taken = imu_taken_s(self.ekf.config, args[0]) if kind == "fuse_imu" else args[0]
        heapq.heappush(self._held, (taken, next(self._order), kind, args))
        if kind == "fuse_imu":
            self.imu_s = max(self.imu_s, taken)
            self.imu_stamp_s = max(self.imu_stamp_s, args[0])
        self._fuse_until(self.imu_s)

    def tick(self, t_s: float) -> None:
        """The loop's tick at ``t_s`` (s): with the IMU silent longer than ``max_age_s`` (its
        newest stamp that old), fuse every held sample and predict the filter to ``t_s``."""
        if t_s - self.imu_stamp_s > self.max_age_s:
            self.flush()
            if t_s - self.ekf.t > self.max_age_s:
                self.ekf.advance(t_s)

    def flush(self) -> None:
        """Fuse every held sample (the run's end: no IMU sample will come)."""
        self._fuse_until(math.inf)

    def _fuse_until(self, t_s: float) -> None:
        while self._held and self._held[0][0] <= t_s:
            _, _, kind, args = heapq.heappop(self._held)
            getattr(self.ekf, kind)(*args)
