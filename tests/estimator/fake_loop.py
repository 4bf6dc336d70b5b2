"""Test helper: what a run-loop handler writes to and fuses into, recorded."""


class Stream:
    """A log stream that keeps its rows."""

    def __init__(self):
        self.rows = []

    def write(self, *row):
        self.rows.append(row)


class Ekf:
    """A filter that keeps the times it was asked to fuse samples at."""

    def __init__(self):
        self.fused_at = []

    def fuse_imu(self, t_s, *_):
        self.fused_at.append(t_s)

    def fuse_wheels(self, t_s, *_):
        self.fused_at.append(t_s)
