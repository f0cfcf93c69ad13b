#!/usr/bin/env python3
"""Writes the robustness suite's sweep files from a split's manifest.

    python3 robustness/make_sweeps.py robustness/inputs/tune [--only invert,sdf]
        [--cases N] [--recipe NAME:KEY=VALUE;KEY=VALUE ...] [--no-paper]

One sweep per front-end, beside the manifest (`invert.toml`, `sdf.toml`, `flame.toml`,
`points.toml`): every case of the front-end's families as one value of the `case` axis (its
file, its truth and its true map count), crossed with the recipes as groups: `ifslab` (the
defaults: nothing set) and `paper` (`paper = true`), plus any `--recipe` given (a name and
overrides, for tuning). `invert` runs each case with the true N (`CASE@true`) and 10 maps
(`CASE@ten`; a 10-map code once). Each run's config
is what the front-end's command line says at its defaults:

    ifslab invert FILE --maps N           ↔ problem = "image", target.image, model.maps
    ifslab sdf fit FILE --pattern P --depth K
    ifslab flame learn FILE
    ifslab fit-points FILE --k K

plus the file of the code or pattern that drew it (`target.truth`, `truth`), which only
adds scores against it to the run's summary. Standard library only.
"""

import argparse
import json
import os
import sys


def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise TypeError(v)


def inline(d):
    return "{ " + ", ".join(f"{json.dumps(k)} = {toml_value(v)}" for k, v in d.items()) + " }"


def parse_recipe(text):
    """`name:key=value;key=value` → (name, {key: value}) with TOML-ish values."""
    name, _, rest = text.partition(":")
    sets = {}
    for item in filter(None, rest.split(";")):
        k, _, v = item.partition("=")
        v = v.strip()
        try:
            val = json.loads(v)
        except json.JSONDecodeError:
            val = v
        sets[k.strip()] = val
    return name, sets


FRONT_ENDS = {
    "invert": {
        "base": {"problem": "image"},
        "case": lambda c: {
            "target.image": c["file"],
            "target.truth": c["truth"],
            "model.maps": c["maps"],
        },
        # Each case twice, with the true N (`@true`) and with 10 maps (`@ten`); a code of
        # 10 maps once (both are the same run, which a sweep refuses to hold twice).
        "variants": lambda c: [("true", {})] + ([("ten", {"model.maps": 10})] if c["maps"] != 10 else []),
        "extra_axes": [],
        "slurm": {"cpus_per_task": 2, "time": "00:30:00", "mem": "4G"},
    },
    "sdf": {
        "base": {"problem": "sdf"},
        "case": lambda c: {
            "target": c["file"],
            "truth": c["truth"],
            "pattern": c["pattern"],
            "depth": min(c["depth"], 5),
        },
        "extra_axes": [],
        "slurm": {"cpus_per_task": 2, "time": "00:10:00", "mem": "2G"},
    },
    "flame": {
        "base": {"problem": "flame"},
        "case": lambda c: {"target": c["file"]},
        "extra_axes": [],
        "slurm": {"cpus_per_task": 2, "time": "00:20:00", "mem": "2G"},
    },
    "points": {
        "base": {"problem": "points"},
        "case": lambda c: {"data": c["file"], "truth": c["truth"], "k": c["k"]},
        "extra_axes": [],
        "slurm": {"cpus_per_task": 2, "time": "00:20:00", "mem": "2G"},
    },
}


def write_sweep(split_dir, name, cases, recipes, split, suffix=""):
    fe = FRONT_ENDS[name]
    lines = [
        f"# The robustness suite's `{name}` runs on the {split} split, written by",
        "# robustness/make_sweeps.py from manifest.json (do not edit: regenerate).",
        f"#   ifslab sweep {os.path.join(split_dir, name + suffix + '.toml')} -o OUT --jobs 1",
        f'name = "robustness_{split}_{name}{suffix}"',
        "",
        "[base]",
    ]
    for k, v in fe["base"].items():
        if isinstance(v, list) and v and isinstance(v[0], dict):
            continue
        lines.append(f"{k} = {toml_value(v)}")
    for k, v in fe["base"].items():
        if isinstance(v, list) and v and isinstance(v[0], dict):
            for item in v:
                lines.append("")
                lines.append(f"[[base.{k}]]")
                for kk, vv in item.items():
                    lines.append(f"{kk} = {toml_value(vv)}")
    lines.append("")
    lines.append("[slurm]")
    for k, v in fe["slurm"].items():
        lines.append(f"{k} = {toml_value(v)}")
    for rname, rset in recipes:
        lines += ["", "[[group]]", f'name = "{rname}"']
        if rset:
            lines.append(f"set = {inline(rset)}")
    lines += ["", "[[axis]]", 'name = "case"']
    for c in cases:
        sets = {k: v for k, v in fe["case"](c).items() if v is not None}
        variants = fe["variants"](c) if "variants" in fe else [(None, {})]
        for variant, more in variants:
            label = c["id"] if variant is None else f'{c["id"]}@{variant}'
            lines += ["[[axis.value]]", f'label = "{label}"', f"set = {inline({**sets, **more})}"]
    for axis, values in fe["extra_axes"]:
        lines += ["", "[[axis]]", f'name = "{axis}"']
        for label, sets in values:
            lines += ["[[axis.value]]", f'label = "{label}"']
            if sets:
                lines.append(f"set = {inline(sets)}")
    path = os.path.join(split_dir, f"{name}{suffix}.toml")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("split_dir", help="a split's folder (holding manifest.json)")
    ap.add_argument("--only", default="invert,sdf,flame,points")
    ap.add_argument("--cases", type=int, default=0,
                    help="the first N cases of each family only (0: all)")
    ap.add_argument("--families", default="", help="only these families (comma-separated)")
    ap.add_argument("--recipe", action="append", default=[],
                    help="NAME:KEY=VALUE;KEY=VALUE, a further group (tuning)")
    ap.add_argument("--no-paper", action="store_true", help="leave out the paper's recipe")
    ap.add_argument("--no-default", action="store_true", help="leave out ifslab's defaults")
    ap.add_argument("--suffix", default="", help="written as NAME<suffix>.toml")
    a = ap.parse_args()
    manifest = json.load(open(os.path.join(a.split_dir, "manifest.json")))
    split = manifest["split"]
    recipes = []
    if not a.no_default:
        recipes.append(("ifslab", {}))
    if not a.no_paper:
        recipes.append(("paper", {"paper": True}))
    recipes += [parse_recipe(r) for r in a.recipe]
    fams = set(filter(None, a.families.split(",")))
    for name in filter(None, a.only.split(",")):
        cases = [c for c in manifest["cases"] if c["front_end"] == name]
        if fams:
            cases = [c for c in cases if c["family"] in fams]
        if a.cases:
            kept, seen = [], {}
            for c in cases:
                seen[c["family"]] = seen.get(c["family"], 0) + 1
                if seen[c["family"]] <= a.cases:
                    kept.append(c)
            cases = kept
        if not cases:
            continue
        path = write_sweep(a.split_dir, name, cases, recipes, split, a.suffix)
        print(f"{path}: {len(cases)} cases × {len(recipes)} recipes", file=sys.stderr)


if __name__ == "__main__":
    main()
