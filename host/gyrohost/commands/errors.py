"""The one error a subcommand raises for a user's mistake, and how a device step's errors map onto
the exit statuses (0 ok, 1 failed, 2 bad usage or input)."""

import sys
from collections.abc import Callable

from gyrohost.errors import GyrohostError


class CliError(GyrohostError, ValueError):
    """A user-facing error: printed as ``gyrotens: error: <message>``, exit status 2."""


def device_step(command: str, step: Callable[[], object]) -> int:
    """Run ``step`` (one library call); 0 when it returns. Bad input (a ``ValueError`` kind of
    :class:`GyrohostError`: a file, a key, a port, a limit) becomes :class:`CliError`, exit 2;
    a device failing on the way prints one line ``gyrotens COMMAND: error: ...`` and gives 1."""
    try:
        step()
    except ValueError as exc:
        if isinstance(exc, GyrohostError):
            raise CliError(str(exc)) from None
        raise
    except (GyrohostError, OSError) as exc:
        print(f"gyrotens {command}: error: {exc}", file=sys.stderr)
        return 1
    return 0


def executor_status(command: str, exc: GyrohostError) -> int:
    """The exit status of an executor's error (:class:`~gyrohost.parallel.ExecutorError`): Dask
    losing cases is a failure, printed, 1; no Dask or no scheduler is bad input, exit 2."""
    from gyrohost.parallel import CasesLost

    if isinstance(exc, CasesLost):
        print(f"gyrotens {command}: error: {exc}", file=sys.stderr)
        return 1
    raise CliError(str(exc)) from None
