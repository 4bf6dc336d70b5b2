"""Ctrl-C (SIGINT) handled differently inside a block, for the code that must not be cut short.

Python delivers signals to the main thread only, so in any other thread these contexts do nothing
(a Ctrl-C then reaches the main thread's handler as usual).
"""

import signal
import threading


class SigintHandled:
    """Context: inside, SIGINT calls ``handler(signum, frame)``; the previous handler is restored
    on exit.

    Parameters
    ----------
    handler : callable(signum, frame)
    """

    def __init__(self, handler):
        self.handler = handler
        self.previous = None

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self.previous = signal.signal(signal.SIGINT, self.handler)
        return self

    def __exit__(self, *exc):
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)
        return False


class SigintHeld(SigintHandled):
    """Context: a Ctrl-C inside is handed to the previous handler as the block exits, so a
    ``KeyboardInterrupt`` cannot land in the middle of it (a message half read from a pipe)."""

    def __init__(self):
        super().__init__(self._hold)
        self.pending = None

    def _hold(self, signum, frame):
        self.pending = (signum, frame)

    def __exit__(self, *exc):
        previous = self.previous
        super().__exit__(*exc)
        if previous is None or self.pending is None:
            return False
        if callable(previous):
            previous(*self.pending)  # KeyboardInterrupt, or the safe state's note
        elif previous == signal.SIG_DFL:
            signal.raise_signal(signal.SIGINT)
        return False
