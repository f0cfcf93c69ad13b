"""Sweeps, `collect` and suite scores from Python, against the `ifslab` binary's."""

from __future__ import annotations

import csv
import subprocess
import sys
import json
from pathlib import Path

import pytest

import ifslab

from conftest import cli_error_lines

PACKED = "paper_repro/chaotic_splatting/results/sweep_em_sierpinski"

BASE = """\
iterations = 3
checkpoint_every = 3
[target]
code = "sierpinski"
size = 32
[model]
maps = 3
init = "em"
[generator]
trajectories = 100
length = 40
warmup = 10
[renderer]
supersample = 2
"""

SWEEP = """\
name = "py_tiny"
base = "base.toml"
[[axis]]
key = "seed"
values = [0, 1]
"""


def test_collect_of_a_packed_sweep_equals_the_cli(repo: Path, cli, tmp_path: Path) -> None:
    folder = repo / PACKED
    assert (folder / "runs.jsonl.gz").is_file()
    cli(["collect", folder, "-o", tmp_path / "report"])
    expected = json.loads((tmp_path / "report" / "results.json").read_text())
    c = ifslab.collect(folder)
    assert c.results == expected
    assert len(c.runs) == len(expected["runs"]) > 1
    for mine, theirs in zip(c.runs, expected["runs"]):
        assert mine == theirs
    assert c.sweep == expected["sweep"] and c.axes == expected["axes"]
    assert c.counts["finished"] == len(c.runs)
    # The aggregates are the means of the rows' numbers, group by group.
    rows = list(csv.DictReader((tmp_path / "report" / "results.csv").open()))
    assert [r["id"] for r in rows] == [r["id"] for r in c.runs]
    axis = c.axes[0]
    agg = ifslab.collect(folder, by=axis).aggregates
    assert len(agg) == 1 and agg[0]["by"] == [axis]
    metric = "iou" if "iou" in c.metrics else c.metrics[0]
    for g in agg[0]["groups"]:
        values = [
            float(r[metric]) for r in rows if r[axis] == g["labels"][0] and r[metric] != ""
        ]
        assert g["runs"] == sum(r[axis] == g["labels"][0] for r in rows)
        assert g["stats"][metric]["count"] == len(values)
        assert g["stats"][metric]["mean"] == pytest.approx(sum(values) / len(values), rel=1e-12)


def test_collect_writes_the_report_the_cli_writes(repo: Path, cli, tmp_path: Path) -> None:
    cli(["collect", repo / PACKED, "-o", tmp_path / "cli"])
    c = ifslab.collect(repo / PACKED, output=tmp_path / "py")
    assert c.report == tmp_path / "py" / "report.md" and c.report.is_file()
    for name in ("results.json", "results.csv"):
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes()


def test_sweep_runs_then_adopts_its_finished_runs(tmp_path: Path) -> None:
    (tmp_path / "base.toml").write_text(BASE)
    (tmp_path / "sweep.toml").write_text(SWEEP)
    out = tmp_path / "out"
    events = []
    done = ifslab.sweep(tmp_path / "sweep.toml", out, jobs=1, progress=lambda e, v: events.append((e, v)))
    assert [r["status"] for r in done["runs"]] == ["finished", "finished"]
    assert all("3 iterations" in r["headline"] for r in done["runs"])
    assert ("start", ("runs", 2)) in events and ("position", 2) in events
    for r in done["runs"]:
        assert (out / "runs" / r["id"] / "run.json").is_file()
    c = ifslab.collect(out)
    assert len(c.runs) == 2 and c.counts["finished"] == 2
    assert [r["labels"]["seed"] for r in c.runs] == ["0", "1"]
    stamp = {r["id"]: (out / "runs" / r["id"] / "run.json").stat().st_mtime_ns for r in c.runs}
    again = ifslab.sweep(tmp_path / "sweep.toml", out)
    assert [r["status"] for r in again["runs"]] == ["skipped", "skipped"]
    assert stamp == {r["id"]: (out / "runs" / r["id"] / "run.json").stat().st_mtime_ns for r in c.runs}
    # A shard takes every other run.
    half = ifslab.sweep(tmp_path / "sweep.toml", out, shard="1/2")
    assert [r["index"] for r in half["runs"]] == [1]


def test_suite_score_equals_the_cli(cli, tmp_path: Path) -> None:
    suite = tmp_path / "suite"
    cli(["suite", "make", "--codes", "2", "--tier", "smoke", "--patches", "1", "-o", suite])
    code_file = tmp_path / "fern.json"
    ifslab.save_code("fern", code_file)
    expected = json.loads(cli(["suite", "score", suite, "--index", "1", code_file, "--json"]).stdout)
    for code in ("fern", code_file, ifslab.code("fern")):
        got = ifslab.suite.score(code, suite, index=1)
        del got["seconds"]
        assert got == {k: v for k, v in expected.items() if k != "seconds"}
    assert len(expected["views"]) == 2 and expected["index"] == 1
    every = ifslab.suite.score("fern", suite)
    assert [s["index"] for s in every] == [0, 1]
    assert every[1]["iou"] == expected["iou"]


def test_errors_carry_the_library_words(cli, tmp_path: Path) -> None:
    # A missing folder or file: FileNotFoundError, as everywhere in the package.
    missing = tmp_path / "nowhere"
    with pytest.raises(FileNotFoundError) as e:
        ifslab.collect(missing)
    theirs = cli_error_lines(cli(["collect", missing, "-o", tmp_path / "r"], check=False).stderr)
    assert str(e.value) == ": ".join(theirs)
    with pytest.raises(FileNotFoundError) as e:
        ifslab.sweep(tmp_path / "no_sweep.toml", tmp_path / "out")
    theirs = cli_error_lines(cli(["sweep", tmp_path / "no_sweep.toml", "-o", tmp_path / "out"], check=False).stderr)
    assert str(e.value) == ": ".join(theirs)
    with pytest.raises(FileNotFoundError) as e:
        ifslab.suite.score("fern", missing, index=0)
    ifslab.save_code("fern", tmp_path / "fern.json")
    theirs = cli_error_lines(
        cli(["suite", "score", missing, "--index", "0", tmp_path / "fern.json"], check=False).stderr
    )
    assert str(e.value) == ": ".join(theirs)
    # A folder that is no sweep's, a sweep file that is wrong, an index out of the suite:
    # IfslabError with the command line's words.
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "sweep.json").write_text("{}")
    with pytest.raises(ifslab.IfslabError) as e:
        ifslab.collect(tmp_path / "empty")
    theirs = cli_error_lines(cli(["collect", tmp_path / "empty", "-o", tmp_path / "r"], check=False).stderr)
    assert str(e.value) == ": ".join(theirs)
    (tmp_path / "base.toml").write_text(BASE)
    (tmp_path / "bad.toml").write_text(SWEEP.replace('key = "seed"', 'key = "sed"'))
    with pytest.raises(ifslab.IfslabError) as e:
        ifslab.sweep(tmp_path / "bad.toml", tmp_path / "out")
    theirs = cli_error_lines(cli(["sweep", tmp_path / "bad.toml", "-o", tmp_path / "out"], check=False).stderr)
    assert str(e.value) == ": ".join(theirs)
    suite = tmp_path / "suite"
    cli(["suite", "make", "--codes", "1", "--tier", "smoke", "--patches", "1", "-o", suite])
    with pytest.raises(ifslab.IfslabError) as e:
        ifslab.suite.score("fern", suite, index=5)
    theirs = cli_error_lines(
        cli(["suite", "score", suite, "--index", "5", tmp_path / "fern.json"], check=False).stderr
    )
    assert str(e.value) == ": ".join(theirs)
    (tmp_path / "sweep.toml").write_text(SWEEP)
    with pytest.raises(ifslab.IfslabError, match="not a shard"):
        ifslab.sweep(tmp_path / "sweep.toml", tmp_path / "out", shard="x")
    with pytest.raises(ifslab.IfslabError, match="jobs must be at least 1"):
        ifslab.sweep(tmp_path / "sweep.toml", tmp_path / "out", jobs=0)
    assert not (tmp_path / "out").exists()



INTERRUPTED = """
import os, signal, sys
# Python leaves SIGINT ignored when it starts with it ignored (a test command run in the
# background of a non-interactive shell): Ctrl-C's handler is put back, as a terminal has it.
signal.signal(signal.SIGINT, signal.default_int_handler)
import ifslab

sent = []

def progress(event, value):
    # A real SIGINT, as Ctrl-C sends it, once the short run is done and the long one begins.
    if event == "position" and value >= 1 and not sent:
        sent.append(value)
        os.kill(os.getpid(), signal.SIGINT)

try:
    ifslab.sweep(sys.argv[1], sys.argv[2], progress=progress)
except KeyboardInterrupt as e:
    print("KeyboardInterrupt:", e)
    sys.exit(3)
print("finished")
"""


def test_ctrl_c_stops_a_sweep_and_the_next_call_does_the_rest(tmp_path: Path) -> None:
    (tmp_path / "base.toml").write_text(BASE)
    (tmp_path / "sweep.toml").write_text(
        SWEEP.replace('key = "seed"\nvalues = [0, 1]', 'key = "iterations"\nvalues = [3, 1500]')
    )
    out = tmp_path / "out"
    done = subprocess.run(
        [sys.executable, "-c", INTERRUPTED, str(tmp_path / "sweep.toml"), str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 3, done.stdout + done.stderr
    assert "KeyboardInterrupt: interrupted: the runs under way stopped at a checkpoint" in done.stdout
    c = ifslab.collect(out)
    assert [r["status"] for r in c.runs] == ["finished", "interrupted"], c.runs
    again = ifslab.sweep(tmp_path / "sweep.toml", out)
    assert [r["status"] for r in again["runs"]] == ["skipped", "finished"]
    assert "1500 iterations" in again["runs"][1]["headline"]


SWEEP3 = """\
name = "py_flags"
base = "base.toml"
[[axis]]
key = "seed"
values = [0, 1, 2]
"""


def _three(tmp_path: Path) -> Path:
    (tmp_path / "base.toml").write_text(BASE)
    (tmp_path / "sweep.toml").write_text(SWEEP3)
    return tmp_path / "sweep.toml"


def test_only_and_dry_run_are_the_clis(cli, tmp_path: Path) -> None:
    file = _three(tmp_path)
    out = tmp_path / "out"
    plan = ifslab.sweep(file, out, dry_run=True)
    assert [r["state"] for r in plan["runs"]] == ["not_started"] * 3
    assert all(r["in_shard"] for r in plan["runs"])
    printed = cli(["sweep", file, "-o", out, "--dry-run"]).stdout
    assert printed.startswith(plan["description"]) and plan["description"]
    # --only: one run, run; the dry run then says so, for every way of naming it.
    done = ifslab.sweep(file, out, only={"seed": 1}, without_lpips=True)
    assert [(r["index"], r["status"]) for r in done["runs"]] == [(1, "finished")]
    for only in ({"seed": [1]}, ["seed=1"], [("seed", 1)], "seed=1"):
        one = ifslab.sweep(file, out, dry_run=True, only=only)
        assert [(r["index"], r["state"]) for r in one["runs"]] == [(1, "finished")], only
    printed = cli(["sweep", file, "-o", out, "--dry-run", "--only", "seed=1"]).stdout
    assert printed.startswith(one["description"])
    assert "1 finished" in printed
    everything = ifslab.sweep(file, out, dry_run=True, shard="0/2")
    assert [r["state"] for r in everything["runs"]] == ["not_started", "finished", "not_started"]
    assert [r["in_shard"] for r in everything["runs"]] == [True, False, True]
    # Refusals in the library's words, and flags that do not go together.
    bad = cli(["sweep", file, "-o", out, "--dry-run", "--only", "colour=red"], check=False)
    assert bad.returncode != 0
    with pytest.raises(ifslab.IfslabError) as e:
        ifslab.sweep(file, out, dry_run=True, only={"colour": "red"})
    assert cli_error_lines(bad.stderr)[0] in str(e.value)
    with pytest.raises(ValueError, match="AXIS=LABEL"):
        ifslab.sweep(file, out, dry_run=True, only=["seed"])
    with pytest.raises(ValueError, match="do not go together"):
        ifslab.sweep(file, out, dry_run=True, slurm=True)
    with pytest.raises(ValueError, match="slurm=True"):
        ifslab.sweep(file, out, submit=True)


def test_adopt_takes_finished_runs_as_the_cli_does(cli, tmp_path: Path) -> None:
    file = _three(tmp_path)
    first = tmp_path / "first"
    ifslab.sweep(file, first, only={"seed": [0, 2]})
    mine = ifslab.sweep(file, tmp_path / "py", adopt=first / "runs")
    cli(["sweep", file, "-o", tmp_path / "cli", "--adopt", first / "runs"])
    assert sorted(r["index"] for r in mine["adopted"]) == [0, 2]
    assert mine["already"] == 0
    # Only the sweep's own lock folder is no run.
    assert [Path(u["folder"]).name for u in mine["unmatched"]] == [".locks"]
    for name in ("py", "cli"):
        c = ifslab.collect(tmp_path / name)
        assert [r["status"] for r in c.runs] == ["finished", "missing", "finished"], name
    again = ifslab.sweep(file, tmp_path / "py", adopt=first / "runs")
    assert again["adopted"] == [] and again["already"] == 2
    # Adopted runs are not run again.
    rest = ifslab.sweep(file, tmp_path / "py")
    assert [r["status"] for r in rest["runs"]] == ["skipped", "finished", "skipped"]


def test_slurm_writes_the_clis_script(cli, tmp_path: Path) -> None:
    from conftest import _cli_path

    file = _three(tmp_path)
    exe = _cli_path().resolve()
    mine = ifslab.sweep(file, tmp_path / "py", slurm=True, exe=exe, only={"seed": [0, 1]}, without_lpips=True)
    printed = cli(
        ["sweep", file, "-o", tmp_path / "cli", "--slurm", "--only", "seed=0", "--only", "seed=1", "--without-lpips"]
    ).stdout
    script = Path(mine["script"])
    assert script.is_file() and script.parent == (tmp_path / "py" / "slurm").resolve()
    assert mine["runs"] == 2 and f"{mine['runs']} runs in {mine['array_tasks']} array tasks" in printed
    assert mine["job"] is None
    theirs = (tmp_path / "cli" / "slurm" / "sweep.sbatch").read_text()
    text = script.read_text()
    assert "--without-lpips" in text
    assert text.replace(str((tmp_path / "py").resolve()), "OUT") == theirs.replace(
        str((tmp_path / "cli").resolve()), "OUT"
    )
    with pytest.raises(ifslab.IfslabError, match="not there"):
        ifslab.sweep(file, tmp_path / "x", slurm=True, exe=tmp_path / "no-such-ifslab")
