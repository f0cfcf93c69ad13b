#!/usr/bin/env python3
"""Collects results/runs/*/summary.json into results/summary.md (a Markdown table)."""
import json
import pathlib
import sys

out = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "results")
rows = []
for s in sorted(out.glob("runs/*/summary.json")):
    d = json.loads(s.read_text())
    start, strategy, target = s.parent.name.split("-", 2)
    rows.append((target, start, strategy, d))

lines = [
    "| target | start | strategy | IoU | PSNR (dB) | SSIM | final loss | iterations | time (s) |",
    "|---|---|---|---|---|---|---|---|---|",
]
for target, start, strategy, d in sorted(rows, key=lambda r: (r[0], r[1], r[2])):
    lines.append(
        f"| {target} | {start} | {strategy} | {d['iou']:.3f} | {d['psnr']:.2f} | {d['ssim']:.3f} "
        f"| {d['final_loss']:.3f} | {d['iterations']} | {d['seconds']:.0f} |"
    )
by = {}
for target, start, strategy, d in rows:
    by.setdefault((start, strategy), []).append(d["iou"])
lines += ["", "| start | strategy | mean IoU | targets |", "|---|---|---|---|"]
for (start, strategy), v in sorted(by.items()):
    lines.append(f"| {start} | {strategy} | {sum(v) / len(v):.3f} | {len(v)} |")
(out / "summary.md").write_text("\n".join(lines) + "\n")
print("\n".join(lines))
