"""The simulated rig in a child process, for runs in real time.

In one interpreter the rig's truth model, its emulators, the drivers and the estimator share
one GIL and fall behind real time together; in a child process the rig has an interpreter of
its own and the host side sees only its pseudo-terminals, as it would see hardware. The child
also sends every truth step's state up a pipe every ``period_s``, each stamped with
``time.monotonic_ns()`` when stepped (a system-wide clock, so the parent maps it to its own run
time), and answers fault injections and statistics requests.

An interrupt (Ctrl-C, SIGTERM, SIGHUP) that arrives while the parent receives is held until the
message is whole: a ``KeyboardInterrupt`` inside ``Connection.recv`` would leave the rest of the
message in the pipe, read next as a broken message (``EOFError``) although the child is alive.
(A reader thread would avoid that too, but under CPU load its GIL hand-offs made the loop's ticks
late by 0.3 s.) Every failure of the pipe (the child gone, a broken pipe) is a
:class:`RigProcessError`.
"""

import multiprocessing
import time
from dataclasses import dataclass

import numpy as np

from gyrohost.gcfreeze import heap_frozen
from gyrohost.sigint import InterruptsHeld, ignore_interrupts

from .errors import RigProcessError

READY_TIMEOUT_S = 60.0
"""Longest wait for the child to import, build the rig and report its ptys, s."""


_PIPE_ERRORS = (EOFError, OSError)
"""What a closed or broken pipe raises (BrokenPipeError is an OSError)."""


@dataclass(frozen=True)
class TruthSample:
    """The truth at one instant.

    Attributes
    ----------
    t_ns : int
        ``time.monotonic_ns`` when the truth took this step, ns.
    rig_t_s : float
        Rig (device) time then, s.
    truth_t_s : float
        Time of the truth's latest step, s: behind ``rig_t_s`` when the truth lags or slips.
    state_rig_t_s : float
        Rig time the truth's state belongs to (its step's time plus the slip), s: what the
        devices showed of it then.
    N : ndarray, shape (3, n), m
        Scene node positions.
    omega_w_rad_s : ndarray, shape (n_w,), rad/s
        True wheel spins (scene wheel order).
    rest_length_m : ndarray, shape (alpha,), m
        True string rest lengths (scene order).
    """

    t_ns: int
    rig_t_s: float
    truth_t_s: float
    state_rig_t_s: float
    N: np.ndarray
    omega_w_rad_s: np.ndarray
    rest_length_m: np.ndarray


class RigProcess:
    """A :class:`~gyrohost.simrig.sim.SimulatedRig` (real clock) served by a child process.

    Parameters
    ----------
    config : RigConfig
    period_s : float, s
        How often the truth's steps since the last are sent.

    Attributes
    ----------
    paths : dict
        Device name -> pty path.
    t0_ns : int
        ``time.monotonic_ns`` at rig time zero, ns (rig time runs with the wall clock while the
        rig keeps up; under load it slips behind).
    node_names, string_names : list of str
    n_wheels : int
    """

    def __init__(self, config, period_s: float = 0.01):
        ctx = multiprocessing.get_context("spawn")
        self._conn, child = ctx.Pipe()
        self._proc = ctx.Process(
            target=_serve, args=(child, config, period_s), name="gyrotens-rig", daemon=True
        )
        self._proc.start()
        child.close()
        self._pending: list[TruthSample] = []
        reply = self._reply("ready", READY_TIMEOUT_S)
        self.paths = reply["paths"]
        self.t0_ns = reply["t0_ns"]
        self.node_names = reply["node_names"]
        self.string_names = reply["string_names"]
        self.n_wheels = reply["n_wheels"]

    def truth(self) -> list[TruthSample]:
        """Truth samples received since the last call (never waits).

        Raises
        ------
        RigProcessError
            The rig reported an error, or the pipe to it broke.
        """
        with InterruptsHeld():
            while self._poll(0.0):
                self._take(self._recv())
        out, self._pending = self._pending, []
        return out

    def inject(self, device: str, fault: str, **kwargs) -> None:
        """Inject a fault now (arguments of ``SimulatedRig.inject``)."""
        self._send(("inject", (device, fault), kwargs))
        self._reply("injected")

    def command(self, line: str) -> str:
        """Run one text command of ``gyrotens rig`` (``SimulatedRig.command``: ``reset``, ...);
        returns its answer."""
        self._send(("command", (line,), {}))
        return self._reply("answer")["text"]

    def stats(self) -> dict:
        """The rig's rates and truth timing: ``lines`` (text) and ``real_time`` (whether the
        truth kept it, and the figures: :meth:`RigStats.real_time`)."""
        self._send(("stats", (), {}))
        return self._reply("stats")

    def close(self) -> None:
        """Stop the child (idempotent)."""
        if self._proc.is_alive():
            try:
                self._conn.send(("close", (), {}))
            except OSError:
                pass  # the child is gone already
            self._proc.join(5.0)
            if self._proc.is_alive():
                self._proc.terminate()
                self._proc.join(1.0)
        self._conn.close()

    def __enter__(self) -> "RigProcess":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _send(self, msg) -> None:
        try:
            self._conn.send(msg)
        except _PIPE_ERRORS as exc:
            raise RigProcessError(f"simulated rig: cannot send '{msg[0]}': {exc!r}") from exc

    def _poll(self, timeout_s: float) -> bool:
        try:
            return self._conn.poll(timeout_s)
        except _PIPE_ERRORS as exc:
            raise RigProcessError(f"simulated rig: the pipe to the rig ended: {exc!r}") from exc

    def _recv(self):
        try:
            return self._conn.recv()
        except _PIPE_ERRORS as exc:
            raise RigProcessError(f"simulated rig: the pipe to the rig ended: {exc!r}") from exc

    def _take(self, msg) -> dict | None:
        kind, body = msg
        if kind == "truth":
            self._pending += [TruthSample(*step) for step in body]
            return None
        if kind == "error":
            raise RigProcessError(f"simulated rig: {body}")
        return {"kind": kind, **body}

    def _reply(self, kind: str, timeout_s: float = 5.0) -> dict:
        deadline = time.monotonic() + timeout_s
        while True:
            left = deadline - time.monotonic()
            if left <= 0 or not self._proc.is_alive() and not self._poll(0.0):
                raise RigProcessError(f"simulated rig: no '{kind}' reply within {timeout_s:g} s")
            with InterruptsHeld():
                reply = self._take(self._recv()) if self._poll(min(left, 0.1)) else None
            if reply is not None and reply["kind"] == kind:
                return reply


def _serve(conn, config, period_s: float) -> None:
    """Child process: build and start the rig, stream the truth, answer requests."""
    from gyrohost.simrig.sim import SimulatedRig

    ignore_interrupts()  # Ctrl-C, SIGTERM, SIGHUP are the parent's: it still needs the rig
    try:
        rig = SimulatedRig(config, clock="real")
    except Exception as exc:  # reported to the parent, which raises it
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
        return
    # the truth's steps are real-time work too; frozen once the rig is built and before its
    # device threads start, which the collection would hold up
    with heap_frozen():
        _start_and_serve(conn, rig, period_s)


def _start_and_serve(conn, rig, period_s: float) -> None:
    """Start the built rig, report ready, then stream its truth and answer requests."""
    from gyrohost.simrig.errors import FaultCommandError

    try:
        rig.keep_truth_steps()
        t0_ns = time.monotonic_ns()  # rig time zero (start() reads the clock right after)
        rig.start()
    except Exception as exc:  # reported to the parent, which raises it
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
        return
    truth = rig.truth
    conn.send(
        (
            "ready",
            {
                "paths": rig.paths,
                "t0_ns": t0_ns,
                "node_names": list(truth.node_names),
                "string_names": [s.name for s in truth.model.scene.strings],
                "n_wheels": len(truth.wheel_input_rad_s),
            },
        )
    )
    next_s = time.monotonic()
    try:
        while True:
            if rig.loop_error is not None:
                conn.send(("error", f"the rig loop stopped: {rig.loop_error!r}"))
                return
            if conn.poll(max(next_s - time.monotonic(), 0.0)):
                kind, args, kwargs = conn.recv()
                if kind == "close":
                    return
                if kind == "inject":
                    try:
                        rig.inject(*args, **kwargs)
                        conn.send(("injected", {}))
                    except FaultCommandError as exc:
                        conn.send(("error", str(exc)))
                elif kind == "command":
                    try:
                        conn.send(("answer", {"text": rig.command(*args)}))
                    except FaultCommandError as exc:
                        conn.send(("error", str(exc)))
                elif kind == "stats":
                    s = rig.stats()
                    lines = [s.rates_line(), s.truth_line()]
                    conn.send(("stats", {"lines": lines, "real_time": s.real_time()}))
                continue
            next_s += period_s
            steps = rig.truth_steps()
            if steps:
                conn.send(("truth", steps))
    except (EOFError, BrokenPipeError, KeyboardInterrupt):
        return
    finally:
        rig.close()
