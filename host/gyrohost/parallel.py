"""One executor for independent cases: serial in this process, or Dask tasks on a cluster.

Used by ``gyrotens sweep`` (:mod:`gyrohost.sweep`), the estimator's Monte Carlo
(:mod:`gyrohost.sil.montecarlo`) and the independent cases of ``gyrotens bench``. Every
case is one call ``fn(item)``; the results come back in the order of the items, whichever worker
finished first.

- ``serial``: plain calls in this process, one after the other (timing runs that must not share
  cores; nothing is pickled).
- ``scheduler="tcp://host:8786"``: a running Dask scheduler (``dask scheduler`` /
  ``dask worker`` on other machines, docs/sweeps.md); its workers must have this package.
- otherwise: a ``LocalCluster`` of ``workers`` single-threaded processes (default: this machine's
  cores), started on entry and closed on exit.

Dask (``dask[distributed]``, the ``sweep`` extra) is imported only when a cluster is asked for.
On Dask, ``fn`` and the items travel pickled: use module-level functions (or
:func:`functools.partial` of them) and plain data, and rebuild models inside the task.
"""

import logging
import os
import threading
import traceback
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from gyrohost.errors import GyrohostError

STALL_CHECK_S = 5.0
"""How often a map waiting on Dask asks whether any worker still runs one of its cases, s."""
STALL_S = 60.0
"""How long every worker may sit idle while cases are pending before the map gives up, s: Dask
hands a waiting case to an idle worker within milliseconds, so a minute of idleness means it
lost the case (its scheduler and a worker disagreeing), and would otherwise wait forever."""


class ExecutorError(GyrohostError, RuntimeError):
    """The executor cannot run: Dask is not installed, the scheduler cannot be reached, or it
    lost cases."""


class CasesLost(ExecutorError):
    """Dask lost cases: its workers sat idle while they were pending."""


@dataclass(frozen=True)
class Failure:
    """A case that raised, kept in place of its result (``keep_going``).

    Attributes
    ----------
    error : str
        ``"ExceptionType: message"``.
    traceback : str
        The formatted traceback (from the worker on Dask).
    """

    error: str
    traceback: str

    @classmethod
    def of(cls, exc: BaseException, tb=None) -> "Failure":
        text = "".join(traceback.format_exception(type(exc), exc, tb or exc.__traceback__))
        return cls(f"{type(exc).__name__}: {exc}", text)


class Executor:
    """Runs ``fn(item)`` for every item, serially or as Dask tasks; a context manager.

    Parameters
    ----------
    serial : bool
        Run in this process, one case after the other.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); else a ``LocalCluster``.
    workers : int, optional
        Worker processes of the ``LocalCluster`` (one thread each); default ``os.cpu_count()``.
    progress : bool
        Show Dask's text progress bar while the cases run (not in serial mode).
    timeout_s : float, s
        How long to try to reach ``scheduler``.
    """

    def __init__(self, serial=False, scheduler=None, workers=None, progress=False, timeout_s=10.0):
        if workers is not None and workers < 1:
            raise ExecutorError(f"workers: {workers} (need at least 1)")
        self.serial = serial
        self.scheduler = scheduler
        self.workers = workers
        self.progress = progress
        self.timeout_s = timeout_s
        self.client = None
        self._cluster = None

    def describe(self) -> str:
        """Where the cases run, one line."""
        if self.serial:
            return "serial, in this process"
        if self.scheduler:
            return f"Dask scheduler {self.scheduler}"
        return f"Dask LocalCluster of {self.workers or os.cpu_count()} worker processes"

    def slots(self) -> int:
        """How many cases run at once: 1 serially, else the Dask workers' threads (a
        ``LocalCluster``'s planned workers before it starts)."""
        if self.serial:
            return 1
        if self.client is not None:
            workers = self.client.scheduler_info().get("workers", {})
            return max(sum(w.get("nthreads", 1) for w in workers.values()), 1)
        return self.workers or os.cpu_count() or 1

    def __enter__(self):
        if self.serial:
            return self
        try:
            from distributed import Client, LocalCluster
        except ImportError as exc:
            raise ExecutorError(
                f"Dask is not installed ({exc}): pip install 'gyrotensegrity[sweep]', "
                "or pass --serial"
            ) from None
        try:
            if self.scheduler:
                self.client = Client(self.scheduler, timeout=f"{self.timeout_s}s")
            else:
                self._cluster = LocalCluster(
                    n_workers=self.workers or os.cpu_count(),
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    silence_logs=logging.CRITICAL,  # a failed case is reported by the caller
                )
                self.client = Client(self._cluster)
        except (OSError, ValueError) as exc:  # unreachable, or an address Dask cannot parse
            self.close()
            raise ExecutorError(f"Dask scheduler {self.scheduler}: {exc}") from None
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        """Close the client and the ``LocalCluster`` started for it (if any)."""
        for part in (self.client, self._cluster):
            if part is not None:
                part.close()
        self.client = self._cluster = None

    def map(
        self,
        fn: Callable,
        items: Iterable,
        keep_going: bool = False,
        on_done: Callable | None = None,
    ) -> list:
        """``[fn(item) for item in items]``, each call one case.

        Parameters
        ----------
        keep_going : bool
            A case that raises gives a :class:`Failure` in its place and the others go on;
            otherwise the first exception (in the order the cases finish) is raised.
        on_done : callable ``on_done(index, result)``, optional
            Called in this process as each case finishes (a result or a :class:`Failure`), in
            the order they finish: a caller keeps finished cases although a later one is lost.

        Returns
        -------
        list
            The results in the order of ``items``.
        """
        items = list(items)
        if self.serial:
            return [
                self._serial_one(fn, k, item, keep_going, on_done) for k, item in enumerate(items)
            ]
        if self.client is None:
            raise ExecutorError("Executor.map outside its with-block: no Dask client")
        return self._dask_map(fn, items, keep_going, on_done)

    @staticmethod
    def _serial_one(fn, k, item, keep_going, on_done):
        try:
            result = fn(item)
        except Exception as exc:
            if not keep_going:
                raise
            result = Failure.of(exc)
        if on_done is not None:
            on_done(k, result)
        return result

    def _dask_map(self, fn, items, keep_going, on_done):
        from distributed import progress

        futures = [self.client.submit(fn, item, pure=False) for item in items]
        index = {f.key: k for k, f in enumerate(futures)}
        bar = None
        if self.progress and futures:
            bar = threading.Thread(target=progress, args=(futures,), kwargs={"multi": False})
            bar.start()
        results: list = [None] * len(items)
        try:
            for future in self._finished(futures, index):
                k = index[future.key]
                if future.status == "error":
                    if not keep_going:
                        future.result()  # raises the case's exception with its traceback
                    results[k] = Failure.of(future.exception(), future.traceback())
                else:
                    results[k] = future.result()
                if on_done is not None:
                    on_done(k, results[k])
        finally:
            self.client.cancel([f for f in futures if not f.done()])
            if bar is not None:
                bar.join(timeout=5.0)
        return results

    def _finished(self, futures, index):
        """The futures as they finish (those of one wait in the items' order); an
        :class:`CasesLost` naming the cases left when every worker has sat idle for
        :data:`STALL_S` with cases pending."""
        from distributed import wait

        pending, idle_s = set(futures), 0.0
        while pending:
            try:
                done, pending = wait(pending, timeout=STALL_CHECK_S, return_when="FIRST_COMPLETED")
            except TimeoutError:
                idle_s = idle_s + STALL_CHECK_S if self._workers_idle() else 0.0
                if idle_s >= STALL_S:
                    cases = sorted(index[f.key] for f in pending)
                    raise CasesLost(
                        f"Dask lost {len(cases)} case(s) (items {cases}): no worker has run "
                        f"any for {idle_s:g} s while they were pending; run again, or --serial"
                    ) from None
                continue
            idle_s = 0.0
            yield from sorted(done, key=lambda f: index[f.key])

    def _workers_idle(self) -> bool:
        """No worker runs a task, by the workers' own account (the scheduler's may be what
        went wrong)."""
        return not any(self.client.run(_executing).values())


def _executing(dask_worker) -> int:
    """Tasks the worker runs now (called on it by :meth:`Executor._workers_idle`)."""
    return dask_worker.state.executing_count


def add_arguments(parser, serial_default=False) -> None:
    """Add ``--serial``, ``--scheduler ADDRESS``, ``--workers N`` to an argparse parser.

    Parameters
    ----------
    serial_default : bool
        Serial unless ``--scheduler`` or ``--workers`` is given (timing runs); else Dask
        unless ``--serial``.
    """
    group = parser.add_argument_group("where the cases run (docs/sweeps.md)")
    group.add_argument("--serial", action="store_true", help="one after the other in this process")
    group.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler")
    group.add_argument(
        "--workers", type=int, metavar="N", help="LocalCluster worker processes (default: cores)"
    )
    parser.set_defaults(serial_default=serial_default)


def from_args(args, progress=False) -> Executor:
    """The :class:`Executor` the options of :func:`add_arguments` ask for."""
    chosen = args.scheduler is not None or args.workers is not None
    serial = args.serial or (args.serial_default and not chosen)
    return Executor(
        serial=serial, scheduler=args.scheduler, workers=args.workers, progress=progress
    )
