"""Interrupting signals (SIGINT, SIGTERM, SIGHUP) handled differently inside a block, for the code
that must not be cut short.

Ctrl-C (SIGINT), ``kill`` (SIGTERM) and a closed terminal or ssh session (SIGHUP) all mean "stop
now": :class:`InterruptsRaised` turns SIGTERM and SIGHUP into a ``KeyboardInterrupt`` naming
the signal, so whatever ends a run on Ctrl-C ends it on them too, and :func:`exit_status` gives
the shell's status (128 + signal). Python delivers signals to the main
thread only, so in any other thread these contexts do nothing (a signal then reaches the main
thread's handler as usual).
"""

import signal
import threading

INTERRUPTS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""The signals that mean "stop now"."""


def interrupt_signal(exc: KeyboardInterrupt) -> signal.Signals:
    """The signal behind an interrupt: the one its argument names (raised by
    :class:`InterruptsRaised`), else SIGINT (Python's own Ctrl-C)."""
    name = exc.args[0] if exc.args else None
    known = isinstance(name, str) and name in signal.Signals.__members__
    return signal.Signals[name] if known else signal.SIGINT


def signal_name(exc: KeyboardInterrupt) -> str:
    """``Ctrl-C`` for SIGINT, else the signal's name (``SIGTERM``)."""
    signum = interrupt_signal(exc)
    return "Ctrl-C" if signum == signal.SIGINT else signum.name


def exit_status(exc: KeyboardInterrupt) -> int:
    """The shell's exit status of a process ended by this interrupt: 128 + signal (130 Ctrl-C)."""
    return 128 + interrupt_signal(exc)


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


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt(signal.Signals(signum).name)


class InterruptsRaised(InterruptsHandled):
    """Context: inside, SIGTERM and SIGHUP raise ``KeyboardInterrupt("SIGTERM")`` (or
    ``"SIGHUP"``); SIGINT keeps its handler (Python's own raises ``KeyboardInterrupt``)."""

    def __init__(self):
        super().__init__(_raise_interrupt, (signal.SIGTERM, signal.SIGHUP))


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
            handler(signum, frame)  # KeyboardInterrupt, or the safe state's note
        elif handler == signal.SIG_DFL:
            signal.raise_signal(signum)
        return False


class InterruptsBlocked:
    """Context: the interrupting signals blocked in this thread. A process started inside
    inherits the block (across ``fork`` and ``exec``), so a Ctrl-C to the process group cannot
    cut its start short (a traceback from its interpreter's start-up): it unblocks them once it
    has chosen what to do with them (:func:`unblock_interrupts`).

    multiprocessing's resource tracker, started with a process's first child, unblocks SIGINT
    and SIGTERM in the starting thread once it runs: it is started before the block, so that
    the block holds for the child started inside it."""

    def __enter__(self):
        self.previous = None
        if hasattr(signal, "pthread_sigmask"):  # POSIX
            from multiprocessing import resource_tracker

            resource_tracker.ensure_running()
            self.previous = signal.pthread_sigmask(signal.SIG_BLOCK, INTERRUPTS)
        return self

    def __exit__(self, *exc):
        if self.previous is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, self.previous)
        return False


def unblock_interrupts() -> None:
    """Unblock the interrupting signals in this thread (a child started blocked, after it set
    their handlers)."""
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, INTERRUPTS)
