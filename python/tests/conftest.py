"""Shared fixtures: the repository's files and the `ifslab` binary to compare with."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import List

import pytest

REPO = Path(__file__).resolve().parents[2]


def _cli_path() -> Path:
    return Path(os.environ.get("IFSLAB_CLI", REPO / "target" / "ci" / "ifslab"))


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture(scope="session")
def cli():
    """Runs the `ifslab` binary (IFSLAB_CLI, else target/ci/ifslab, which the test script's
    cargo tests build). Where IFSLAB_CLI names it (as scripts/test.sh does) a missing
    binary fails the tests that compare with it; otherwise they are skipped."""
    path = _cli_path()
    if not path.is_file():
        if "IFSLAB_CLI" in os.environ:
            pytest.fail(f"IFSLAB_CLI={path} is not a file")
        pytest.skip(f"no ifslab binary at {path} (cargo build --profile ci -p ifslab-experiments)")

    def run(args: List[str], check: bool = True, cwd=None) -> subprocess.CompletedProcess:
        env = dict(os.environ, RUST_BACKTRACE="0")
        done = subprocess.run(
            [str(path), *map(str, args)], capture_output=True, text=True, cwd=cwd, env=env
        )
        if check and done.returncode != 0:
            raise AssertionError(f"ifslab {' '.join(map(str, args))} failed:\n{done.stderr}")
        return done

    return run


def cli_error_lines(stderr: str) -> List[str]:
    """The lines of the error the binary printed (anyhow's `Error: …` and its causes)."""
    text = stderr[stderr.index("Error: ") + len("Error: ") :].split("Stack backtrace:")[0]
    lines = [l.strip() for l in text.splitlines()]
    return [l.split(": ", 1)[1] if l[:1].isdigit() and ": " in l else l for l in lines if l and l != "Caused by:"]


def without_seconds(log: Path) -> List[List[str]]:
    """The rows of a run's log.csv without its wall-clock column (`seconds`): every
    number a run computes, which must agree to the bit."""
    rows = [line.split(",") for line in log.read_text().splitlines()]
    keep = [i for i, name in enumerate(rows[0]) if name != "seconds"]
    assert len(keep) == len(rows[0]) - 1, rows[0]
    return [[r[i] for i in keep] for r in rows]
