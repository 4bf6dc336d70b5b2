"""A sweep end to end: cases through the executor, kept in DIR, one Parquet table, plots.

DIR holds ``spec.toml`` (the spec as run), ``cases/<case_id>.json`` (one file per finished
case, written as it finishes: a sweep stopped half way keeps what it did), ``results.parquet``
(one row per case: ``case``, ``case_id``, the axes, the recorded quantities and ``error``, null
for a case that ran) and the figures. A case whose file holds a result is not run again; a
failed case is (a lost worker deserves another try).
"""

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from gyrohost.parallel import Executor, Failure

from . import plots
from .case import run_case, tasks
from .errors import SweepSizeError
from .spec import Spec, case_count, cases

MAX_CASES = 10_000
"""Cases a sweep may have unless the user allows more (``--max-cases``, ``--yes``): every case's
row (a few kB with its scene) is held until the table is written, and at the shipped sweep's
fraction of a second a case, ten thousand already take hours on a workstation. A larger count is
more often a mistyped ``num`` than a plan."""


def check_size(spec: Spec, max_cases: int | None) -> int:
    """The number of cases of ``spec`` (:func:`.spec.case_count`), refused above ``max_cases``
    (``None``: any number).

    Raises
    ------
    SweepSizeError
        More cases than ``max_cases``; the message says how many, from which axes, and how to
        allow them.
    """
    n = case_count(spec)
    if max_cases is not None and n > max_cases:
        sizes = " x ".join(f"{a.name} {len(a.values)}" for a in spec.axes)
        how = sizes if spec.sampling == "grid" else f"sweep.cases = {n}"
        raise SweepSizeError(
            f"{spec.path}: {n} cases ({how}), more than the {max_cases} allowed: check the "
            "axes' num (a typo?), or allow them with --max-cases N (or --yes)"
        )
    return n


@dataclass
class SweepResult:
    """Rows of the table (dicts, case order), counts and the files written."""

    rows: list
    ran: int
    kept: int
    failed: int
    files: list = field(default_factory=list)


def run_sweep(spec: Spec, out: Path, executor: Executor, on_first=None) -> SweepResult:
    """Run the cases of ``spec`` not yet finished in ``out`` and write the table and figures.

    The caller checks the number of cases first (:func:`.spec.case_count`): every case's row is
    held until the table is written.

    Parameters
    ----------
    executor : gyrohost.parallel.Executor
        Entered (``with``) by the caller; the cases run with ``keep_going``.
    on_first : callable ``on_first(pending, first_s)``, optional
        With more than one case to run, the first runs alone; then this gets the number of
        cases to run and the first one's wall time, s (to estimate the rest's).
    """
    out = Path(out)
    folder = out / "cases"
    folder.mkdir(parents=True, exist_ok=True)
    (out / "spec.toml").write_text(spec.path.read_text())
    todo = list(tasks(spec, cases(spec)))
    done = {t.case_id: _read_case(folder / f"{t.case_id}.json") for t in todo}
    pending = [t for t in todo if done[t.case_id] is None or done[t.case_id]["error"]]

    def keeper(offset):
        def keep(k, result):
            task = pending[offset + k]
            done[task.case_id] = _write_case(folder, spec, task, result)

        return keep

    first = 1 if on_first is not None and len(pending) > 1 else 0
    if first:
        start = time.perf_counter()
        executor.map(run_case, pending[:1], keep_going=True, on_done=keeper(0))
        on_first(len(pending), time.perf_counter() - start)
    executor.map(run_case, pending[first:], keep_going=True, on_done=keeper(first))
    rows = [done[t.case_id] for t in todo]
    result = SweepResult(
        rows,
        ran=len(pending),
        kept=len(todo) - len(pending),
        failed=sum(r["error"] is not None for r in rows),
    )
    result.files.append(write_table(rows, out / "results.parquet"))
    ok = [r for r in rows if r["error"] is None]
    figures = [
        plots.heatmap(spec, ok, out / "heatmap.png"),
        plots.pareto(spec, ok, out / "pareto.png"),
    ]
    result.files += [f for f in figures if f is not None]
    return result


def _read_case(path: Path) -> dict | None:
    """A finished case's row, None when there is none (or the file is torn)."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _write_case(folder: Path, spec: Spec, task, result) -> dict:
    """The row of a case written to its file (atomically: a stop leaves no torn file)."""
    row = {"case": task.index, "case_id": task.case_id}
    row |= {a.name: v for a, v in zip(spec.axes, task.values, strict=True)}
    failed = isinstance(result, Failure)
    row |= {q: None for q in spec.record} if failed else result
    row["error"] = result.error if failed else None
    if failed:
        row["traceback"] = result.traceback
    path = folder / f"{task.case_id}.json"
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(row))
    os.replace(tmp, path)
    return row


def write_table(rows: list, path: Path) -> Path:
    """``rows`` as one Parquet table (pyarrow); the traceback stays in the case files."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist([{k: v for k, v in r.items() if k != "traceback"} for r in rows])
    pq.write_table(table, path)
    return path


def read_table(path: Path) -> list:
    """The rows of a ``results.parquet`` (dicts)."""
    import pyarrow.parquet as pq

    return pq.read_table(path).to_pylist()
