"""Sweeps and their results: ``ifslab sweep FILE -o DIR`` and ``ifslab collect DIR`` from
Python, through the library functions those commands call (``run_sweep``, ``collect``,
``write_report``)."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, Iterable, List, Optional, Sequence, Union

from . import _ifslab
from ._progress import reporting

PathLike = Union[str, "os.PathLike[str]"]


def sweep(
    sweep_file: PathLike,
    output: PathLike,
    jobs: int = 1,
    *,
    threads: Optional[int] = None,
    shard: Optional[str] = None,
    progress: Any = None,
) -> Dict[str, Any]:
    """Runs the sweep file ``sweep_file`` into the folder ``output`` on this machine, as
    ``ifslab sweep FILE -o OUTPUT --jobs JOBS [--threads T] [--shard I/N]`` does: runs
    already finished there (in folders or packed) are kept, interrupted ones resumed,
    failed ones re-done. ``progress`` (a callable ``(event, value)`` or ``True`` for tqdm)
    hears the sweep's runs done. Ctrl-C stops the runs under way at their checkpoints and
    raises ``KeyboardInterrupt``; calling again resumes them. A failed run raises
    :class:`IfslabError` naming it (its folder stays in ``runs/.ID.partial``).

    Returns ``{"sweep", "dir", "jobs", "threads", "runs": [{"index", "id", "name",
    "status", …}]}``, status ``finished`` (now, with its ``headline``), ``skipped``
    (finished before), ``busy`` (another process holds it)."""
    with reporting(progress) as callback:
        text = _ifslab.sweep(
            os.fspath(sweep_file), os.fspath(output), jobs, threads, shard, callback
        )
    return json.loads(text)


@dataclass
class Collected:
    """A sweep folder's results, as ``ifslab collect`` reads them.

    ``runs``: one dict per planned run, in sweep order (``results.json``'s ``runs``: id,
    name, problem, status, labels by axis, run_seconds, summary, …); ``axes``; ``metrics``
    (the summary fields that are numbers); ``counts`` (finished, failed, interrupted,
    not_started); ``aggregates``: per grouping, ``{"by", "metrics", "groups": [{"labels",
    "runs", "stats": {metric: {"mean", "std", "count"} or None}}]}``; ``report``: the report's
    Markdown file (``report.md`` in the report folder), when one was written."""

    sweep: str
    dir: Path
    axes: List[str]
    runs: List[Dict[str, Any]]
    metrics: List[str]
    counts: Dict[str, int]
    unplanned: int
    aggregates: List[Dict[str, Any]]
    report: Optional[Path] = None
    results: Dict[str, Any] = field(default_factory=dict, repr=False)


def collect(
    sweep_dir: PathLike,
    by: Union[str, Sequence[Union[str, Sequence[str]]], None] = None,
    *,
    output: Optional[PathLike] = None,
) -> Collected:
    """The results of the sweep folder ``sweep_dir`` (what ``ifslab sweep -o`` wrote, packed
    or not) as a :class:`Collected`: ``results`` is the document ``ifslab collect`` writes
    as ``results.json``. ``by`` groups the aggregates as ``--by`` does: an axis, a
    comma-joined combination (``"group,strategy"``), or a list of those (default: each
    varying axis alone). With ``output``, the report folder (tables, plots, Markdown) is
    written there as ``ifslab collect DIR -o OUTPUT`` writes it."""
    groupings = _groupings(by)
    text = _ifslab.collect_sweep(
        os.fspath(sweep_dir), groupings, None if output is None else os.fspath(output)
    )
    doc = json.loads(text)
    results = doc["results"]
    return Collected(
        sweep=results["sweep"],
        dir=Path(doc["dir"]),
        axes=list(results["axes"]),
        runs=list(results["runs"]),
        metrics=list(doc["metrics"]),
        counts=dict(doc["counts"]),
        unplanned=int(doc["unplanned"]),
        aggregates=list(doc["aggregates"]),
        report=None if doc["report"] is None else Path(doc["report"]),
        results=results,
    )


def _groupings(by: Union[str, Iterable[Any], None]) -> List[List[str]]:
    if by is None:
        return []
    if isinstance(by, str):
        by = [by]
    out: List[List[str]] = []
    for b in by:
        if isinstance(b, str):
            out.append([s.strip() for s in b.split(",") if s.strip()])
        else:
            out.append([str(s) for s in b])
    return out
