#!/usr/bin/env python3
"""Collects results/runs/*/summary.json into results/summary.md (Markdown tables).

Run folders are named START-STRATEGY-TARGET-sSEED. Per (target, start, strategy) the table
gives the mean over seeds with the per-seed IoUs; the second table averages over the
targets every start/strategy pair was run on, so the rows compare like with like.
"""
import json
import pathlib
import statistics
import sys

out = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "results")
runs = {}
for s in sorted(out.glob("runs/*/summary.json")):
    d = json.loads(s.read_text())
    stem, _, seed = s.parent.name.rpartition("-s")
    start, strategy, target = stem.split("-", 2)
    runs.setdefault((target, start, strategy), []).append((int(seed), d))

mean = statistics.fmean
lines = [
    "| target | start | strategy | IoU mean | IoU per seed | PSNR (dB) | SSIM | time / run (s) |",
    "|---|---|---|---|---|---|---|---|",
]
for (target, start, strategy), rs in sorted(runs.items()):
    rs.sort(key=lambda r: r[0])
    ious = [d["iou"] for _, d in rs]
    lines.append(
        f"| {target} | {start} | {strategy} | **{mean(ious):.3f}** | "
        + " ".join(f"{v:.2f}" for v in ious)
        + f" | {mean(d['psnr'] for _, d in rs):.2f} | {mean(d['ssim'] for _, d in rs):.3f} "
        f"| {mean(d['seconds'] for _, d in rs):.0f} |"
    )

common = {"sierpinski", "fern", "maple"}
lines += [
    "",
    "Averaged over the three targets every pair was run on (Sierpiński, fern, maple); "
    "a run counts as a recovery at IoU ≥ 0.6:",
    "",
    "| start | strategy | mean IoU | recoveries | runs |",
    "|---|---|---|---|---|",
]
pairs = sorted({(st, sg) for (_, st, sg) in runs})
for st, sg in pairs:
    if not common <= {t for (t, a, b) in runs if (a, b) == (st, sg)}:
        continue  # compare only pairs run on every common target
    v = [d["iou"] for (t, a, b), rs in runs.items() if (a, b) == (st, sg) and t in common for _, d in rs]
    if v:
        lines.append(f"| {st} | {sg} | {mean(v):.3f} | {sum(x >= 0.6 for x in v)} | {len(v)} |")
lines += ["", "EM start over all six targets:", "", "| strategy | mean IoU | recoveries | runs |", "|---|---|---|---|"]
for st, sg in pairs:
    if st != "em":
        continue
    v = [d["iou"] for (t, a, b), rs in runs.items() if (a, b) == (st, sg) for _, d in rs]
    lines.append(f"| {sg} | {mean(v):.3f} | {sum(x >= 0.6 for x in v)} | {len(v)} |")
(out / "summary.md").write_text("\n".join(lines) + "\n")
print("\n".join(lines))
