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

for group in ["fig5b", "fig5b-defaults"]:
    d = root / group
    if d.exists():
        out.append(f"\n### {group}: proportion converged (v_D >= 0.95 after 300 iterations)\n")
        sweeps = sorted(d.glob("*/pool_sweep.json"))
        pools = [x["pool"] for x in json.loads(sweeps[0].read_text())["results"]] if sweeps else []
        out.append("| run | " + " | ".join(f"pool {p}" for p in pools) + " | seconds |")
        out.append("|---|" + "---|" * (len(pools) + 1))
        for s in sweeps:
            j = json.loads(s.read_text())
            cells = [f'{x["proportion"]:.2f} ({x["converged"]}/{x["repeats"]})' for x in j["results"]]
            out.append(f"| {s.parent.name} | " + " | ".join(cells) + f' | {j["seconds"]:.0f} |')


def sweep_cells(path):
    j = json.loads(path.read_text())
    x = j["results"][0]
    n = x["repeats"]
    return (f'{x["converged"]}/{n}', f'{x["right"]}/{n}' if x.get("right") is not None else "-",
            f'{x["converged_and_right"]}/{n}' if x.get("converged_and_right") is not None else "-",
            f'{x["median_heldout_log_likelihood"]:.3f}', f'{j["seconds"]:.0f}')

d = root / "convergence"
if d.exists():
    out.append("\n### convergence on independent data (pool 10; converged = v_D >= 0.95, right = coverage agreement >= 0.9)\n")
    out.append("| data | defaults: converged | right | both | median held-out | s | paper: converged | right | both | median held-out | s |")
    out.append("|---|---|---|---|---|---|---|---|---|---|---|")
    for s in sorted((d / "defaults").glob("*/pool_sweep.json")):
        p = d / "paper" / s.parent.name / "pool_sweep.json"
        cells = list(sweep_cells(s)) + (list(sweep_cells(p)) if p.exists() else ["-"] * 5)
        out.append(f"| {s.parent.name} | " + " | ".join(cells) + " |")

d = root / "ablation"
if d.exists():
    out.append("\n### ablation: the defaults with one change undone (pool 10, same seeds)\n")
    out.append("| data | variant | converged | right | both | median held-out | s |")
    out.append("|---|---|---|---|---|---|---|")
    for s in sorted(d.glob("*/*/pool_sweep.json")):
        out.append(f"| {s.parent.parent.name} | {s.parent.name} | " + " | ".join(sweep_cells(s)) + " |")

(root / "summary.md").write_text("\n".join(out) + "\n")
print("\n".join(out))
