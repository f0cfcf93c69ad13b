#!/usr/bin/env python3
"""Table 3 or 4's random-start rows: the one shared start against a start drawn per run.

Reads the committed sweep (`results/table3_medium` or `results/table4_medium`, every run
from the one Anderson–Farrell code of seed 0) and its re-run with a start per run
(`results/table3_starts` or `results/table4_starts`, `model.init_seed` = 1000 + the code's
index), both through `ifslab collect`, pairs the runs by (row, code) on the codes the re-run
holds, and prints a Markdown table per metric: each row's mean with the shared start and
with the start per run, the mean paired difference ± its standard error, and on how many
codes the value went up, down or stayed (within `--tie`; for LPIPS, lower is better).

    python3 paper_repro/chaotic_splatting/compare_starts.py table3 [--ifslab BIN]

Standard library only; `ifslab collect` does the reading (packed or unpacked runs alike).
"""

import argparse
import csv
import math
import os
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
AXIS = {"table3": "method", "table4": "ablation"}
METRICS = ["suite.iou", "suite.f1", "suite.lpips"]


def collect(ifslab, folder, axis, out):
    """`ifslab collect` of one sweep folder; its per-run rows."""
    cmd = [ifslab, "collect", folder, "-o", out, "--by", axis]
    for m in METRICS:
        cmd += ["--metric", m]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(os.path.join(out, "results.csv"), newline="") as f:
        return [r for r in csv.DictReader(f) if r["status"] == "finished"]


def by_row_and_code(rows, axis, metric):
    """{(row, code index): value} of the finished runs that report `metric`."""
    out = {}
    for r in rows:
        if r.get(metric, "") != "":
            out[(r[axis], int(r["index"]))] = float(r[metric])
    return out


def mean(xs):
    return sum(xs) / len(xs)


def stderr(xs):
    if len(xs) < 2:
        return float("nan")
    m = mean(xs)
    return math.sqrt(sum((x - m) ** 2 for x in xs) / (len(xs) - 1) / len(xs))


def table(shared, drawn, metric, tie, order):
    """Markdown rows comparing the two, one per row of the table that both hold."""
    lines = [
        f"**{metric}**",
        "",
        "| row | codes | shared start, these codes | start per run | difference ± s.e. | up / down / same | shared start, all codes |",
        "|---|---:|---:|---:|---:|---|---:|",
    ]
    for row in order:
        codes = sorted(c for (r, c) in drawn if r == row and (r, c) in shared)
        if not codes:
            continue
        a = [shared[(row, c)] for c in codes]
        b = [drawn[(row, c)] for c in codes]
        d = [y - x for x, y in zip(a, b)]
        up = sum(1 for x in d if x > tie)
        down = sum(1 for x in d if x < -tie)
        everyone = [v for (r, _), v in shared.items() if r == row]
        lines.append(
            f"| {row} | {len(codes)} | {mean(a):.3f} | {mean(b):.3f} | "
            f"{mean(d):+.3f} ± {stderr(d):.3f} | {up} / {down} / {len(d) - up - down} | "
            f"{mean(everyone):.3f} ({len(everyone)}) |"
        )
    return "\n".join(lines)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("table", choices=sorted(AXIS))
    p.add_argument(
        "--ifslab",
        default=os.path.join(HERE, "..", "..", "target", "release", "ifslab"),
        help="the ifslab binary (default: the release build)",
    )
    p.add_argument("--tie", type=float, default=0.01, help="a change within this is 'same'")
    a = p.parse_args()
    ifslab = a.ifslab if os.path.exists(a.ifslab) else shutil.which("ifslab")
    if ifslab is None:
        sys.exit("no ifslab binary: build it (cargo build --release) or pass --ifslab")
    axis = AXIS[a.table]
    shared_dir = os.path.join(HERE, "results", f"{a.table}_medium")
    drawn_dir = os.path.join(HERE, "results", f"{a.table}_starts")
    if not os.path.isdir(drawn_dir):
        sys.exit(f"{drawn_dir} does not exist: run the sweep {a.table}_starts.toml first")
    with tempfile.TemporaryDirectory() as tmp:
        shared_rows = collect(ifslab, shared_dir, axis, os.path.join(tmp, "shared"))
        drawn_rows = collect(ifslab, drawn_dir, axis, os.path.join(tmp, "drawn"))
    order = []
    for r in drawn_rows:
        if r[axis] not in order:
            order.append(r[axis])
    for metric in METRICS:
        shared = by_row_and_code(shared_rows, axis, metric)
        drawn = by_row_and_code(drawn_rows, axis, metric)
        print(table(shared, drawn, metric, a.tie, order))
        print()


if __name__ == "__main__":
    main()
