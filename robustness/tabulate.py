#!/usr/bin/env python3
"""Tables of the robustness suite: each front-end's score by family and by variation, every
recipe (sweep group) side by side, from the `results.csv` that `ifslab collect` writes.

    python3 robustness/tabulate.py robustness/inputs/test \
        --sdf out/rb/test_sdf --flame out/rb/test_flame \
        --points out/rb/test_points --invert out/rb/test_invert [--invert OTHER ...]

A folder may be a collected sweep (its `report/results.csv` is read), a copy of that
report (`results.csv` in it) or the CSV file itself (`robustness/results/*.csv`, committed). Every front-end is optional; each given one prints a
markdown table. Cases are matched to the split's `manifest.json` by their `case` label.
Standard library only.
"""

import argparse
import csv
import json
import math
import statistics
from collections import OrderedDict
from pathlib import Path

# Per front-end: the score column, the success rule (None: means only), families.
FRONT_ENDS = {
    "sdf": ("truth_iou", lambda v: v >= 0.8, "IoU ≥ 0.8"),
    "flame": ("mse_ratio", lambda v: v <= 0.3, "MSE ≤ 0.3 × flat"),
    "points": ("best.truth_agreement", lambda v: v >= 0.7, "agreement ≥ 0.7"),
    "invert": ("truth.iou", None, "mean shape IoU"),
}


def read_results(folder):
    folder = Path(folder)
    for path in (folder, folder / "report" / "results.csv", folder / "results.csv"):
        if path.is_file():
            with open(path, newline="") as f:
                return list(csv.DictReader(f))
    raise SystemExit(f"{folder}: no results.csv (run `ifslab collect {folder}` first)")


def size_bucket(side):
    if side is None:
        return None
    if side <= 64:
        return "64"
    if side >= 1024:
        return "1024"
    return "128–512"


def case_rows(case):
    """The (variation, value) rows a case counts in, besides its family."""
    v = case.get("variations", {})
    rows = []
    if case["family"] == "photos":
        return rows  # no goal but the family's median: its variations are the shapes'
    if case["family"].startswith("points"):
        noisy = (v.get("noise") or 0) > 0
        outl = (v.get("outliers") or 0) > 0
        cond = {(False, False): "clean", (True, False): "noise",
                (False, True): "1 % outliers", (True, True): "noise + outliers"}[(noisy, outl)]
        rows += [("cloud", cond), ("format", v.get("format")), ("units", v.get("units")),
                 ("K", str(case.get("k")))]
        return rows
    for key in ("line", "polarity", "mode", "format", "framing", "canvas"):
        if v.get(key) is not None:
            rows.append((key, v[key]))
    if "noise" in v and case["family"] != "photos":
        rows.append(("noise", "noisy" if (v.get("noise") or 0) > 0 else "clean"))
    if case.get("background") and isinstance(case["background"], str):
        rows.append(("background", case["background"]))
    side = v.get("longer_side") or max(v.get("width") or 0, v.get("height") or 0) or None
    if size_bucket(side):
        rows.append(("longer side", size_bucket(side)))
    return rows


def fmt_cell(values, rule, refused):
    if not values and not refused:
        return "—"
    finite = [x for x in values if not math.isnan(x)]
    n = len(values) + refused
    if rule is None:
        cell = f"{statistics.fmean(finite):.2f}" if finite else "—"
        return cell + (f" ({refused} refused)" if refused else "")
    ok = sum(1 for x in finite if rule(x))
    mid = f"{statistics.median(finite):.2f}" if finite else "—"
    return f"{ok}/{n} ({mid})" + (f", {refused} refused" if refused else "")


def add(cells, columns, seconds, r, case, col, score):
    """Counts run `r` of `case` in column `col` of every row the case belongs to."""
    columns[col] = None
    if r["status"] not in ("finished", "failed"):
        return  # not run (yet): neither a score nor a refusal
    refused = r["status"] == "failed"
    try:
        value = float(r.get(score) or "nan")
    except ValueError:
        value = float("nan")
    if not refused and r.get("seconds"):
        seconds.setdefault(col, []).append(float(r["seconds"]))
    for row in [("family", case["family"])] + case_rows(case):
        vals, ref = cells.get((row, col), ([], 0))
        if refused:
            ref += 1
        else:
            vals.append(value)
        cells[(row, col)] = (vals, ref)


def common_cases(results):
    """The cases every recipe (group) ran."""
    by_group = {}
    for r in results:
        by_group.setdefault(r["group"], set()).add(r["case"].partition("@")[0])
    return set.intersection(*by_group.values()) if by_group else set()


def table(front, manifest, results, common=False):
    score, rule, what = FRONT_ENDS[front]
    cases = {c["id"]: c for c in manifest["cases"]}
    if common:
        keep = common_cases(results)
        results = [r for r in results if r["case"].partition("@")[0] in keep]
    # Columns: every recipe (group), and for invert every map count as well.
    columns = OrderedDict()
    cells = {}  # (row, column) -> ([scores], refused)
    seconds = {}
    for r in results:
        # `CASE@true` / `CASE@ten` (invert): the map count is part of the label; a code
        # of 10 maps ran once and counts as both. An older sweep had a `maps` column.
        case_id, _, maps = r["case"].partition("@")
        maps = maps or r.get("maps") or ""
        case = cases.get(case_id)
        if case is None:
            raise SystemExit(f"case {r['case']!r} is not in the manifest")
        both = maps == "true" and case.get("maps") == 10
        for m in (["true", "ten"] if both else [maps]):
            add(cells, columns, seconds, r, case, r["group"] + (f", {m} N" if m else ""),
                score)
    rows = OrderedDict()

    for (row, _col) in cells:
        rows[row] = None
    order = sorted(rows, key=lambda rv: (rv[0] != "family", rv[0], rv[1]))
    cols = list(columns)
    out = [f"#### `{front}`: {what} " +
           ("(cells: passed/runs (median))" if rule else "(cells: the mean over the runs)"),
           "",
           "| variation | value | " + " | ".join(cols) + " |",
           "|---|---|" + "---:|" * len(cols)]
    for row in order:
        line = [row[0], row[1]]
        for col in cols:
            vals, ref = cells.get((row, col), ([], 0))
            line.append(fmt_cell(vals, rule, ref))
        out.append("| " + " | ".join(line) + " |")
    med = [f"{statistics.median(seconds[c]):.1f}" if c in seconds else "—" for c in cols]
    out.append("| seconds per run | median | " + " | ".join(med) + " |")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("split_dir", help="a split's folder (holding manifest.json)")
    for front in FRONT_ENDS:
        ap.add_argument(f"--{front}", action="append", default=[],
                        help=f"collected `{front}` sweep folder(s)")
    ap.add_argument("--common", action="store_true",
                    help="only the cases every recipe ran (the paper's invert runs on a subset)")
    a = ap.parse_args()
    manifest = json.load(open(Path(a.split_dir) / "manifest.json"))
    for front in FRONT_ENDS:
        folders = getattr(a, front)
        if not folders:
            continue
        results = [r for folder in folders for r in read_results(folder)]
        print(table(front, manifest, results, a.common))
        print()


if __name__ == "__main__":
    main()
