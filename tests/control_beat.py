"""The host's control thread, as far as the wheel board's heartbeat sees it, in tests.

The board keeps a running wheel alive only on the control frames of the thread that decides the
setpoints (``WheelBoard.heartbeat``, docs/protocol.md); a test that commands a speed and then
waits stands in for that thread with :func:`start_control_thread`.
"""

import threading


def start_control_thread(board, period_s: float = 0.02) -> threading.Event:
    """Call ``board.heartbeat()`` every ``period_s`` (wall time) until the board is closed (its
    port then refuses the write) or the returned event is set (the host "hangs")."""
    stop = threading.Event()

    def beat() -> None:
        while not stop.wait(period_s):
            try:
                board.heartbeat()
            except (OSError, ValueError, TypeError, AttributeError):
                return

    threading.Thread(target=beat, name="test-control", daemon=True).start()
    return stop
