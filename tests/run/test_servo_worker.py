"""The servo worker: goals go out as the loop gives them, each a sample stamped when it went
onto the bus; reads are stamped when sampled."""

import queue
import threading
from types import SimpleNamespace

from gyrohost.run.devices import ServoWorker


class _Bus:
    """Records goals; answers reads with two states sampled at known instants."""

    def __init__(self):
        self.goals = []
        self.sent = threading.Event()
        self.goals_sent_ns = 0

    def command_lengths(self, goals):
        self.goals_sent_ns = 5_000 + len(self.goals)  # the driver's stamp, before its write
        self.goals.append(goals)
        self.sent.set()

    def on_reply_wait(self, hook):
        pass

    def read_states(self):
        return [SimpleNamespace(t_ns=1_000), SimpleNamespace(t_ns=3_000)]


def test_goals_are_sent_at_once_not_at_the_next_read():
    bus, out = _Bus(), queue.Queue()
    worker = ServoWorker(bus, out, rate_hz=0.05).start()  # a read every 20 s
    try:
        first = out.get(timeout=5.0)  # the first read, at start
        worker.command({"s13": 0.40})
        assert bus.sent.wait(5.0), "the goal waited for the next read (20 s)"
        assert bus.goals == [{"s13": 0.40}]
        goal = out.get(timeout=5.0)
        assert (goal.device, goal.t_ns, goal.value) == ("servo_goals", 5_000, {"s13": 0.40})
        assert out.empty()  # no read made for the goal
    finally:
        worker.stop()
    assert not worker.alive
    assert first.device == "servos" and first.t_ns == 2_000  # the servos' sampling instants
