"""Sweeps and their results: ``ifslab sweep FILE -o DIR`` and ``ifslab collect DIR`` from
Python, through the library functions those commands call (``run_sweep``, ``collect``,
``write_report``)."""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, Iterable, List, Optional, Sequence, Union

from . import _ifslab
from ._progress import reporting

PathLike = Union[str, "os.PathLike[str]"]


Only = Union[Dict[str, Any], Iterable[Union[str, Sequence[Any]]], None]


def _only_pairs(only: Only) -> List[tuple]:
    """``only`` as the (axis, label) pairs of ``--only AXIS=LABEL``: a dict of an axis to a
    label or a list of labels, or a list of ``"AXIS=LABEL"`` strings or (axis, label)
    pairs. Labels are compared as text (``seed=0``)."""
    if only is None:
        return []
    pairs: List[tuple] = []
    if isinstance(only, dict):
        for axis, labels in only.items():
            if isinstance(labels, (list, tuple, set)):
                pairs += [(str(axis), str(l)) for l in labels]
            else:
                pairs.append((str(axis), str(labels)))
        return pairs
    if isinstance(only, str):
        only = [only]
    for item in only:
        if isinstance(item, str):
            if "=" not in item:
                raise ValueError(f"`{item}` is not AXIS=LABEL")
            axis, label = item.split("=", 1)
            pairs.append((axis.strip(), label.strip()))
        else:
            axis, label = item
            pairs.append((str(axis), str(label)))
    return pairs


def _ifslab_binary(exe: Optional[PathLike]) -> str:
    """The ``ifslab`` binary Slurm's tasks run: ``exe``, else $IFSLAB_CLI, else the one on
    PATH."""
    if exe is not None:
        return os.fspath(exe)
    found = os.environ.get("IFSLAB_CLI") or shutil.which("ifslab")
    if not found:
        raise _ifslab.IfslabError(
            "a Slurm sweep runs the ifslab binary on each task: give exe=, set IFSLAB_CLI or "
            "put ifslab on PATH (cargo build --release -p ifslab-experiments)"
        )
    return found


def sweep(
    sweep_file: PathLike,
    output: PathLike,
    jobs: int = 1,
    *,
    threads: Optional[int] = None,
    shard: Optional[str] = None,
    only: Only = None,
    without_lpips: bool = False,
    dry_run: bool = False,
    adopt: Optional[PathLike] = None,
    slurm: bool = False,
    submit: bool = False,
    exe: Optional[PathLike] = None,
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
    (finished before), ``busy`` (another process holds it).

    The command's other flags:

    - ``only`` (``--only AXIS=LABEL``, repeated): only the runs with these labels —
      ``{"seed": [0, 1], "group": "em"}``, or ``["seed=0", "seed=1"]``; labels of one axis
      are alternatives, different axes must all match. Applies to every mode below.
    - ``without_lpips`` (``--without-lpips``): run even where the LPIPS weights are missing.
    - ``dry_run`` (``--dry-run``): run nothing; returns ``{"sweep", "dir", "shard",
      "description", "runs": [{"index", "id", "name", "in_shard", "state"}]}``, state
      ``finished``, ``partial`` (interrupted or failed) or ``not_started`` in ``output``.
    - ``adopt`` (``--adopt RUNS_DIR``): run nothing; take the finished run folders of
      ``RUNS_DIR`` (and the runs packed beside it) that are runs of the sweep. Returns
      ``{"sweep", "dir", "adopted": [{"index", "id", "from"}], "already", "unmatched":
      [{"folder", "why"}]}``.
    - ``slurm`` (``--slurm [--submit]``): run nothing; write the job-array script into
      ``output/slurm/`` (tasks running ``exe``, else $IFSLAB_CLI, else ``ifslab`` on PATH)
      and submit it with sbatch when ``submit``. Returns ``{"sweep", "dir", "script",
      "runs", "array_tasks", "job"}``.
    """
    pairs = _only_pairs(only)
    modes = [m for m, on in (("dry_run", dry_run), ("adopt", adopt is not None), ("slurm", slurm)) if on]
    if len(modes) > 1:
        raise ValueError(f"{' and '.join(modes)} do not go together (each runs nothing else)")
    if submit and not slurm:
        raise ValueError("submit= needs slurm=True")
    sweep_file, output = os.fspath(sweep_file), os.fspath(output)
    if dry_run:
        return json.loads(_ifslab.sweep_dry_run(sweep_file, output, shard, pairs))
    if adopt is not None:
        return json.loads(_ifslab.sweep_adopt(sweep_file, output, os.fspath(adopt), pairs))
    if slurm:
        return json.loads(
            _ifslab.sweep_slurm(sweep_file, output, _ifslab_binary(exe), pairs, without_lpips, submit)
        )
    with reporting(progress) as callback:
        text = _ifslab.sweep(
            sweep_file, output, jobs, threads, shard, callback, pairs, without_lpips
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
