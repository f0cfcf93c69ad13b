#!/usr/bin/env python3
"""Which of a points run's fits each rule keeps, on a swept split: the held-out likelihood,
the closeness of the attractor to the cloud (the default), its two directions alone, and
the oracle that keeps the fit agreeing best with the truth.

    python3 robustness/compare_keep.py out/rb/tune3_points [OUT ...]

Each folder is a points sweep's output (its `runs/*/report.json`, which list every fit of a
run with its held-out likelihood, its closeness and its agreement with the truth), so
every rule chooses among the same fits. Prints, per folder, the clouds passed (agreement
≥ 0.7) and the mean agreement under each rule, the clouds on which the closeness keeps a
fit better or worse than the likelihood (by more than 0.005), and those clouds. Standard
library only.
"""

import argparse
import json
from pathlib import Path

PASS = 0.7


def chamfer(r):
    c = r["closeness"]
    return c["data_to_fit"] + c["fit_to_data"]


# Each rule: the fit it keeps among a run's fits.
RULES = {
    "likelihood": lambda runs: max(runs, key=lambda r: r["heldout_log_likelihood"]),
    "closeness": lambda runs: min(runs, key=chamfer),
    "data_to_fit": lambda runs: min(runs, key=lambda r: r["closeness"]["data_to_fit"]),
    "fit_to_data": lambda runs: min(runs, key=lambda r: r["closeness"]["fit_to_data"]),
    "oracle": lambda runs: max(runs, key=lambda r: r["truth_agreement"]),
}


def clouds(folder):
    """(case label, fits) of every finished run with a truth and closeness scores."""
    for report in sorted(Path(folder).glob("runs/*/report.json")):
        runs = json.loads(report.read_text())["em"]["runs"]
        if not runs or runs[0].get("truth_agreement") is None or runs[0].get("closeness") is None:
            continue
        run = json.loads((report.parent / "run.json").read_text())
        yield run.get("name", report.parent.name), runs


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folders", nargs="+")
    a = ap.parse_args()
    for folder in a.folders:
        rows = list(clouds(folder))
        print(f"## {folder}: {len(rows)} clouds\n")
        print("| rule | passed | mean agreement |\n|---|---:|---:|")
        for name, rule in RULES.items():
            kept = [rule(runs)["truth_agreement"] for _, runs in rows]
            passed = sum(v >= PASS for v in kept)
            mean = sum(kept) / max(len(kept), 1)
            print(f"| {name} | {passed}/{len(rows)} | {mean:.3f} |")
        moved = []
        for label, runs in rows:
            lik = RULES["likelihood"](runs)["truth_agreement"]
            close = RULES["closeness"](runs)["truth_agreement"]
            if abs(close - lik) > 0.005:
                moved.append((label, lik, close))
        up = sum(c > l for _, l, c in moved)
        print(f"\ncloseness against likelihood: up on {up}, down on {len(moved) - up}")
        for label, lik, close in moved:
            print(f"- {label}: {lik:.3f} → {close:.3f}")
        print()


if __name__ == "__main__":
    main()
