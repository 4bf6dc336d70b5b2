"""Parameter sweeps of a scene (``gyrotens sweep``, docs/sweeps.md).

:mod:`.spec` reads the spec and expands its cases, :mod:`.case` runs one case (in this process
or on a Dask worker), :mod:`.run` runs them through :class:`gyrohost.parallel.Executor` and keeps
the results, :mod:`.plots` draws them.
"""

from .errors import SpecError
from .run import SweepResult, read_table, run_sweep
from .spec import Spec, load_spec

__all__ = ["Spec", "SpecError", "SweepResult", "load_spec", "read_table", "run_sweep"]
