#!/usr/bin/env python3
"""PSNR and SSIM over the whole crop (background included) beside the foreground-only
values the suite tables report, for the committed runs of codes FIRST..LAST-1 of Table 3
(or of the results folder TABLE names, e.g. `table4_medium`).

Runs made before `ifslab suite score` reported `psnr_crop` / `ssim_crop` lack them in their
summaries; this re-scores their codes (runs whose summaries have them are taken as they are) (deterministic: the same renders as the runs' own
scoring, so the foreground values it prints are the committed ones) and prints the means
per method over all seven views and over the full view alone. It needs the release build
and the medium suite (`make_suite.sh medium`).

With `--write` it also stores the whole-crop values in each re-scored run's `summary.json`
(`suite.psnr_crop`, `suite.ssim_crop` and the same per view, as newer runs write them), so
that `ifslab collect ... --metric suite.ssim_crop` tables them. A summary is only touched
when the re-scored foreground values equal its committed ones (the same code, suite and
renderer), and is replaced atomically (temporary file, then rename).

    python3 paper_repro/chaotic_splatting/crop_metrics.py FIRST LAST [TABLE] [--write]   # from the repository root

The committed runs are packed (`results/TABLE/runs.jsonl.gz`): write their folders back
first with `ifslab unpack paper_repro/chaotic_splatting/results/TABLE`, and after `--write`
pack them again with `ifslab pack paper_repro/chaotic_splatting/results/TABLE --remove`.
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


def same(a, b):
    return abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b))


def write_crop(summary_path, summary, scored):
    """Adds the whole-crop values of `scored` to the run's `summary` and writes it; False
    (and nothing written) when its foreground values differ from the committed ones."""
    suite = summary.get("suite")
    keys = ("f1", "iou", "psnr", "ssim")
    pairs = [(suite, scored)] + list(zip(suite["views"], scored["views"])) if suite else []
    if (
        not suite
        or len(suite["views"]) != len(scored["views"])
        or any(a.get("name") != b.get("name") for a, b in pairs[1:])
        or not all(same(a[k], b[k]) for a, b in pairs for k in keys)
    ):
        return False
    for mine, new in pairs:
        mine["psnr_crop"], mine["ssim_crop"] = new["psnr_crop"], new["ssim_crop"]
    tmp = summary_path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(summary, f, indent=2)
    os.replace(tmp, summary_path)
    return True


def main():
    args = [a for a in sys.argv[1:] if a != "--write"]
    write = len(args) < len(sys.argv) - 1
    first, last = int(args[0]), int(args[1])
    table = args[2] if len(args) > 2 else "table3_medium"
    results = f"{HERE}/results/{table}"
    by_method = {}
    for run_id in sorted(os.listdir(f"{results}/runs")):
        run_json = f"{results}/runs/{run_id}/run.json"
        if run_id.startswith(".") or not os.path.exists(run_json):
            continue
        run = json.load(open(run_json))
        labels = dict(run["labels"])
        index = int(labels.pop("index"))
        method = next(iter(labels.values()))
        code = f"{results}/runs/{run_id}/code.json"
        summary = f"{results}/runs/{run_id}/summary.json"
        if first <= index < last and os.path.exists(code):
            run_summary = json.load(open(summary))
            committed = run_summary.get("suite") or {}
            if "psnr_crop" in committed:
                # Scored by the run itself (or written earlier): nothing to re-score.
                by_method.setdefault(method, []).append(committed)
                continue
            scored = score(index, code)
            by_method.setdefault(method, []).append(scored)
            if write and not write_crop(summary, run_summary, scored):
                print(f"{run_id}: re-scored foreground values differ from the summary's; not written", file=sys.stderr)
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
