#!/usr/bin/env python3
"""Collects results/*/report.json and pool_sweep.json into results/summary.md (Markdown tables)."""
import json, pathlib

root = pathlib.Path(__file__).parent / "results"
out = []

def em_row(name, r):
    em = r["em"]
    runs = em["runs"]
    conv = sum(1 for x in runs if x["converged"])
    best_gmm = max((g for g in r["gmm"] if g["heldout_log_likelihood"] is not None),
                   key=lambda g: g["heldout_log_likelihood"], default=None)
    g = f'{best_gmm["heldout_log_likelihood"]:.3f} ({best_gmm["covariance"]}, M={best_gmm["components"]})' if best_gmm else "-"
    scales = ", ".join(f"{s:.3f}" for s in em["scales"])
    return (f'| {name} | {em["heldout_log_likelihood"]:.3f} | {g} | {conv}/{len(runs)} | '
            f'{em["depth_weights"][-1]:.3f} | {scales} |')

for group in ["fig5a", "fig5a-outermost", "3d"]:
    d = root / group
    if not d.exists():
        continue
    out.append(f"\n### {group}\n")
    out.append("| data, K | EM held-out (nats/pt) | best GMM held-out | converged runs | v_D (best) | scales (best) |")
    out.append("|---|---|---|---|---|---|")
    for rep in sorted(d.glob("*/report.json")):
        out.append(em_row(rep.parent.name, json.loads(rep.read_text())))
    if group == "3d":
        out.append("\nAll Gaussian mixtures (held-out nats/point):\n")
        out.append("| data | covariance | M | parameters | held-out |")
        out.append("|---|---|---|---|---|")
        for rep in sorted(d.glob("*/report.json")):
            r = json.loads(rep.read_text())
            out.append(f'| {rep.parent.name} | IFS (EM) | K={len(r["em"]["scales"])} | {r["em"]["parameters"]} | {r["em"]["heldout_log_likelihood"]:.3f} |')
            for g in r["gmm"]:
                out.append(f'| {rep.parent.name} | {g["covariance"]} | {g["components"]} | {g["parameters"]} | {g["heldout_log_likelihood"]:.3f} |')

d = root / "fig5b"
if d.exists():
    out.append("\n### fig5b: proportion converged (v_D >= 0.95 after 300 iterations)\n")
    sweeps = sorted(d.glob("*/pool_sweep.json"))
    pools = [x["pool"] for x in json.loads(sweeps[0].read_text())["results"]] if sweeps else []
    out.append("| run | " + " | ".join(f"pool {p}" for p in pools) + " | seconds |")
    out.append("|---|" + "---|" * (len(pools) + 1))
    for s in sweeps:
        j = json.loads(s.read_text())
        cells = [f'{x["proportion"]:.2f} ({x["converged"]}/{x["repeats"]})' for x in j["results"]]
        out.append(f"| {s.parent.name} | " + " | ".join(cells) + f' | {j["seconds"]:.0f} |')

(root / "summary.md").write_text("\n".join(out) + "\n")
print("\n".join(out))
