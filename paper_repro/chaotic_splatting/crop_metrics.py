#!/usr/bin/env python3
"""PSNR and SSIM over the whole crop (background included) beside the foreground-only
values the suite tables report, for the committed runs of codes FIRST..LAST-1 of Table 3
(or of the results folder TABLE names, e.g. `table4_medium`).

Runs made before `ifslab suite score` reported `psnr_crop` / `ssim_crop` lack them in their
summaries; this re-scores their codes (deterministic: the same renders as the runs' own
scoring, so the foreground values it prints are the committed ones) and prints the means
per method over all seven views and over the full view alone. It needs the release build
and the medium suite (`make_suite.sh medium`).

    python3 paper_repro/chaotic_splatting/crop_metrics.py FIRST LAST [TABLE]   # from the repository root
"""

import json
import os
import statistics
import subprocess
import sys

HERE = "paper_repro/chaotic_splatting"
SUITE = f"{HERE}/suite/medium"
IFSLAB = "target/release/ifslab"


def score(index, code):
    out = subprocess.run(
        [IFSLAB, "suite", "score", SUITE, "--index", str(index), code, "--json"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return json.loads(out)


def main():
    first, last = int(sys.argv[1]), int(sys.argv[2])
    table = sys.argv[3] if len(sys.argv) > 3 else "table3_medium"
    results = f"{HERE}/results/{table}"
    plan = json.load(open(f"{results}/sweep.json"))
    by_method = {}
    for run in plan["runs"]:
        method, index = run["labels"][0], int(run["labels"][1])
        code = f"{results}/runs/{run['id']}/code.json"
        if first <= index < last and os.path.exists(code):
            by_method.setdefault(method, []).append(score(index, code))
    mean = statistics.mean
    for method, scores in by_method.items():
        full = [s["views"][0] for s in scores]
        print(
            f"{method:24s} codes {len(scores):3d}  "
            f"SSIM fg {mean(s['ssim'] for s in scores):.3f} crop {mean(s['ssim_crop'] for s in scores):.3f}  "
            f"PSNR fg {mean(s['psnr'] for s in scores):5.2f} crop {mean(s['psnr_crop'] for s in scores):5.2f}  "
            f"| full view: SSIM fg {mean(v['ssim'] for v in full):.3f} crop {mean(v['ssim_crop'] for v in full):.3f}  "
            f"PSNR crop {mean(v['psnr_crop'] for v in full):5.2f}"
        )


if __name__ == "__main__":
    main()
