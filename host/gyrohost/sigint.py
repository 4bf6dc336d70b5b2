"""Interrupting signals (SIGINT, SIGTERM, SIGHUP) handled differently inside a block, for the code
that must not be cut short.

Ctrl-C (SIGINT), ``kill`` (SIGTERM) and a closed terminal or ssh session (SIGHUP) all mean "stop
now": :class:`InterruptsRaised` turns SIGTERM and SIGHUP into :class:`Interrupted`, a
``KeyboardInterrupt``, so whatever ends a run on Ctrl-C ends it on them too, and
:func:`exit_status` gives the shell's status (128 + signal). Python delivers signals to the main
thread only, so in any other thread these contexts do nothing (a signal then reaches the main
thread's handler as usual).
"""

import signal
import threading

INTERRUPTS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""The signals that mean "stop now"."""


class Interrupted(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised as an interrupt; ``signum`` is the signal."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def signal_name(exc: KeyboardInterrupt) -> str:
    """``Ctrl-C`` for a plain ``KeyboardInterrupt``, else the signal's name (``SIGTERM``)."""
    return "Ctrl-C" if not isinstance(exc, Interrupted) else signal.Signals(exc.signum).name


def exit_status(exc: KeyboardInterrupt) -> int:
    """The shell's exit status of a process ended by this interrupt: 128 + signal (130 Ctrl-C)."""
    return 128 + getattr(exc, "signum", signal.SIGINT)


def ignore_interrupts() -> None:
    """Ignore every interrupting signal in this process (a child that its parent stops)."""
    for signum in INTERRUPTS:
        signal.signal(signum, signal.SIG_IGN)


class InterruptsHandled:
    """Context: inside, each of ``signals`` calls ``handler(signum, frame)``; the previous
    handlers are restored on exit.

    Parameters
    ----------
    handler : callable(signum, frame)
    signals : tuple of int
        Default: :data:`INTERRUPTS`.
    """

    def __init__(self, handler, signals=INTERRUPTS):
        self.handler = handler
        self.signals = tuple(signals)
        self.previous: dict[int, object] = {}

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self.previous = {s: signal.signal(s, self.handler) for s in self.signals}
        return self

    def __exit__(self, *exc):
        for signum, previous in self.previous.items():
            signal.signal(signum, previous)
        return False


def _raise_interrupted(signum, frame):
    raise Interrupted(signum)


class InterruptsRaised(InterruptsHandled):
    """Context: inside, SIGTERM and SIGHUP raise :class:`Interrupted` (SIGINT keeps its
    handler: Python's own raises ``KeyboardInterrupt``)."""

    def __init__(self):
        super().__init__(_raise_interrupted, (signal.SIGTERM, signal.SIGHUP))


class InterruptsHeld(InterruptsHandled):
    """Context: an interrupting signal inside is handed to its previous handler as the block
    exits, so an interrupt cannot land in the middle of it (a message half read from a pipe)."""

    def __init__(self):
        super().__init__(self._hold)
        self.pending = None

    def _hold(self, signum, frame):
        self.pending = self.pending or (signum, frame)

    def __exit__(self, *exc):
        previous = self.previous
        super().__exit__(*exc)
        if self.pending is None:
            return False
        signum, frame = self.pending
        handler = previous.get(signum)
        if callable(handler):
            handler(signum, frame)  # KeyboardInterrupt, Interrupted, or the safe state's note
        elif handler == signal.SIG_DFL:
            signal.raise_signal(signum)
        return False
