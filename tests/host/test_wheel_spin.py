"""``gyrotens wheels spin``'s library against a fake board: the limits refused before anything is
sent, and Ctrl-C during the spin ramps the wheel down before it is raised again."""

import pytest

from gyrohost.bringup.errors import SetupInputError
from gyrohost.bringup.wheels import SPIN_MAX_RAD_S, SPIN_MAX_S, Spin, spin_wheel
from gyrohost.drivers import wheelproto as wp


class FakeBoard:
    """Records what is sent; its telemetry shows the wheel at the last setpoint (0 once
    stopped); ``interrupt_after`` fault checks raise KeyboardInterrupt, as Ctrl-C would."""

    def __init__(self, interrupt_after: int | None = None):
        self.sent, self.speeds, self.checks = [], [0.0] * 4, 0
        self.interrupt_after = interrupt_after

    def latched_faults(self):
        return []

    def clear_faults(self, names):
        return list(names)

    def set_speeds(self, speeds, confirm=True):
        if confirm or self.sent[-1] != ("SET_SPEEDS", list(speeds)):  # repeats: one entry
            self.sent.append(("SET_SPEEDS", list(speeds)))
        self.speeds = list(speeds)

    def stop_all(self):
        self.sent.append(("STOP_ALL", None))
        self.speeds = [0.0] * 4

    def check_faults(self):
        self.checks += 1
        if self.interrupt_after is not None and self.checks > self.interrupt_after:
            raise KeyboardInterrupt

    @property
    def last_telemetry(self):
        return wp.Telemetry(0, 0, tuple(self.speeds), (0.0,) * 4, 0, 0)


@pytest.mark.parametrize(
    ("wheel", "speed", "duration", "why"),
    [
        (4, 5.0, 1.0, "wheel 4 is not one of 0..3"),
        (0, SPIN_MAX_RAD_S + 1, 1.0, "0 < |speed| <= 20"),
        (0, 0.0, 1.0, "0 < |speed| <= 20"),
        (0, 5.0, SPIN_MAX_S + 1, "0 < time <= 10 s"),
    ],
)
def test_a_spin_out_of_its_limits_sends_nothing(wheel, speed, duration, why):
    board = FakeBoard()
    with pytest.raises(SetupInputError, match=why):
        spin_wheel(board, Spin(wheel, speed, duration), print)
    assert board.sent == []


def test_ctrl_c_ramps_the_wheel_down_then_is_raised():
    board, lines = FakeBoard(interrupt_after=2), []
    with pytest.raises(KeyboardInterrupt):
        spin_wheel(board, Spin(0, -5.0, 2.0), lines.append)
    assert board.sent == [("SET_SPEEDS", [-5.0, 0.0, 0.0, 0.0]), ("STOP_ALL", None)]
    assert lines[-1] == "wheel 0: stopped"


def test_a_spin_reports_the_measured_speed_and_stops():
    board, lines = FakeBoard(), []
    assert spin_wheel(board, Spin(1, 3.0, 0.2), lines.append) == pytest.approx(3.0)
    assert board.sent[-1] == ("STOP_ALL", None)
    assert lines == ["wheel 1: spinning at 3 rad/s, 0.2 s", "wheel 1: measured 3.00 rad/s",
                     "wheel 1: stopped"]  # fmt: skip
