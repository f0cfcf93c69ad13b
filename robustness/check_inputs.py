#!/usr/bin/env python3
"""Checks a suite written by make_inputs.py: files, truths, and truths against pictures.

    python3 check_inputs.py [OUTDIR] [--overlays]

For every split under OUTDIR (default robustness/inputs: tune, tune2, test):
- every listed file exists, opens, and has the recorded size, mode and format;
- every truth file is a valid ifslab-code/1 (finite, shapes, probabilities summing to 1,
  every map contractive) or ifslab-pattern/1 (indices in range, every map's scale < 1);
- each variation value occurs at least 3 times per family (the values the manifest records);
- for the code and pattern families, the truth drawn here (its own chaos game, or sampled
  segments and squares — no code shared with make_inputs.py) over the recorded window agrees
  with the picture: recall = share of the truth's pixels the picture covers (1 px tolerance),
  precision = share of the picture's figure pixels near the truth (1 px + half the line).
  Both must be ≥ 0.9 (0.85 for the tiny 64-pixel pictures).
And every pair of the splits present is disjoint: no seed, random truth or photo crop shared.
--overlays writes OUTDIR/checks/<split>/overlay_<family>.png: picture only green, truth only
magenta, both white.
"""

import argparse
import json
import math
import sys
from collections import Counter
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

HERE = Path(__file__).resolve().parent


def fail(msgs, cid, text):
    msgs.append(f"{cid}: {text}")


# ---------------------------------------------------------------- truth files


def check_code(doc, cid, msgs, dim=None):
    if doc.get("format") != "ifslab-code/1":
        fail(msgs, cid, "code format tag")
    h = doc["dim"]
    if dim is not None and h != dim:
        fail(msgs, cid, f"dim {h}, expected {dim}")
    A, b = [], []
    for i, m in enumerate(doc["maps"]):
        M = np.array(m["matrix"], float)
        t = np.array(m["offset"], float)
        if M.shape != (h, h) or t.shape != (h,):
            fail(msgs, cid, f"map {i} shape")
        if not (np.all(np.isfinite(M)) and np.all(np.isfinite(t))):
            fail(msgs, cid, f"map {i} not finite")
        smax = np.linalg.svd(M, compute_uv=False)[0]
        if not smax < 1.0:
            fail(msgs, cid, f"map {i} not contractive (sigma_max {smax:.6f})")
        A.append(M)
        b.append(t)
    p = np.array(doc["probabilities"], float)
    if len(p) != len(A) or np.any(p < 0) or abs(p.sum() - 1) > 1e-9:
        fail(msgs, cid, "probabilities")
    return np.array(A), np.array(b), p


def check_pattern(doc, cid, msgs):
    if doc.get("format") != "ifslab-pattern/1":
        fail(msgs, cid, "pattern format tag")
    P = np.array([complex(x, y) for x, y in doc["points"]])
    maps = []
    for k, pr in enumerate(doc["pairs"]):
        s0, s1 = pr["source"]
        t0, t1 = pr["target"]
        if max(s0, s1, t0, t1) >= len(P):
            fail(msgs, cid, f"pair {k} index out of range")
            continue
        w = (P[t1] - P[t0]) / (P[s1] - P[s0])
        if not abs(w) < 1:
            fail(msgs, cid, f"pair {k} scale {abs(w):.4f} not < 1")
        maps.append((w, P[t0] - w * P[s0]))
    return P, maps, doc["base"]


# ---------------------------------------------------------------- truth rasters


def window_pixels(xy, win, W, H):
    """Truth coordinates → integer pixel indices (col, row) inside the canvas."""
    x0, y1 = win["min"][0], win["max"][1]
    s = 1.0 / win["pixel"]
    u = np.floor((xy[:, 0] - x0) * s).astype(np.int64)
    v = np.floor((y1 - xy[:, 1]) * s).astype(np.int64)
    ok = (u >= 0) & (u < W) & (v >= 0) & (v < H)
    return u[ok], v[ok], int((~ok).sum())


def truth_code_mask(A, b, p, win, W, H, seed=1):
    rng = np.random.default_rng(seed)
    n_traj, steps = 20000, 60
    x = rng.uniform(-1, 1, (n_traj, 2))
    pts = []
    for s in range(steps + 60):
        idx = rng.choice(len(A), n_traj, p=p)
        x = np.einsum("nij,nj->ni", A[idx], x) + b[idx]
        if s >= 60:
            pts.append(x.copy())
    pts = np.concatenate(pts)
    u, v, outside = window_pixels(pts, win, W, H)
    m = np.zeros((H, W), bool)
    m[v, u] = True
    return m, outside / len(pts)


def words(maps, depth):
    w, t = np.array([1 + 0j]), np.array([0j])
    for _ in range(depth):
        w = np.concatenate([wi * w for wi, _ in maps])
        t = np.concatenate([wi * t + ti for wi, ti in maps])
    return w, t


def truth_pattern_mask(P, maps, base, depth, win, W, H):
    """The leaves of every word of length `depth`, sampled densely: segments as points
    along them, boxes as points filling the square on the diagonal."""
    w, t = words(maps, depth)
    a, c = w * P[base["points"][0]] + t, w * P[base["points"][1]] + t
    step = 0.25 * win["pixel"]
    n = int(np.clip(np.ceil(np.abs(c - a).max() / step), 2, 400))
    u = np.linspace(0, 1, n)
    if base["kind"] == "segment":
        z = a[:, None] + u[None, :] * (c - a)[:, None]
    else:
        # square with diagonal a → c: corners a, m − h, c, m + h; a + s·e1 + r·e2
        m, h = (a + c) / 2, 1j * (c - a) / 2
        e1, e2 = (m - h) - a, (m + h) - a
        s, r = np.meshgrid(u, u)
        z = a[:, None] + s.ravel()[None, :] * e1[:, None] + r.ravel()[None, :] * e2[:, None]
    z = z.ravel()
    pu, pv, outside = window_pixels(np.stack([z.real, z.imag], 1), win, W, H)
    mk = np.zeros((H, W), bool)
    mk[pv, pu] = True
    return mk, outside / len(z)


def dilate(m, r):
    out = m.copy()
    for _ in range(int(r)):
        g = out.copy()
        g[1:] |= out[:-1]
        g[:-1] |= out[1:]
        g[:, 1:] |= out[:, :-1]
        g[:, :-1] |= out[:, 1:]
        out = g
    return out


def hexrgb(h):
    return np.array([int(h[i:i + 2], 16) for i in (1, 3, 5)], float) / 255


def figureness(img, v):
    """0 at the background colour, 1 at the figure's (projection on fg − bg); alpha for RGBA."""
    a = np.asarray(img, float) / 255
    if v["mode"] == "RGBA":
        return a[..., 3]
    if v["mode"] == "L":
        return (a - v["bg"]) / (v["fg"] - v["bg"])
    fg, bg = hexrgb(v["fg"]), hexrgb(v["bg"])
    d = fg - bg
    return ((a - bg) @ d) / (d @ d)


# ---------------------------------------------------------------- main checks


def check_split(split_dir, overlays, out_root):
    man = json.loads((split_dir / "manifest.json").read_text())
    msgs, rows = [], []
    by_family = {}
    for case in man["cases"]:
        by_family.setdefault(case["family"], []).append(case)
    for fam, cases in by_family.items():
        # each recorded variation value several times
        for key in ["polarity", "mode", "format", "framing", "canvas", "line", "units"]:
            cnt = Counter(c["variations"].get(key) for c in cases if key in c["variations"])
            cnt.pop(None, None)
            for val, k in cnt.items():
                if k < 3:
                    fail(msgs, fam, f"variation {key}={val} only {k} times")
        for key in ["maps", "code", "depth", "k", "background", "source"]:
            cnt = Counter(c.get(key) for c in cases if key in c)
            if cnt:
                rows.append((fam, key, dict(sorted(cnt.items()))))
        for key in ["polarity", "mode", "format", "framing", "canvas", "line", "units",
                    "transparent_rgb"]:
            cnt = Counter(c["variations"].get(key) for c in cases if c["variations"].get(key))
            if cnt:
                rows.append((fam, key, dict(sorted(cnt.items()))))
        noisy = sum(1 for c in cases if c["variations"].get("noise"))
        outl = sum(1 for c in cases if c["variations"].get("outliers"))
        rows.append((fam, "noise/outl", f"noisy {noisy}, with outliers {outl}"))
        sizes = [c["variations"]["longer_side"] for c in cases if "longer_side" in c["variations"]]
        if sizes:
            rows.append((fam, "longer_side", f"min {min(sizes)} max {max(sizes)} "
                         f"64:{sizes.count(64)} 1024:{sizes.count(1024)} "
                         f"128-512:{sum(128 <= s <= 512 for s in sizes)}"))
    overlays_by_fam = {}
    stats = {}
    for case in man["cases"]:
        cid, v = case["id"], case["variations"]
        path = split_dir / case["file"]
        if not path.exists():
            fail(msgs, cid, "file missing")
            continue
        truth = None
        if case["truth"]:
            truth = json.loads((split_dir / case["truth"]).read_text())
        if case["front_end"] == "points":
            pts = np.load(path) if path.suffix == ".npy" else np.loadtxt(path, delimiter=",")
            if pts.shape != (case["n_points"], case["dim"]) or not np.all(np.isfinite(pts)):
                fail(msgs, cid, f"cloud shape {pts.shape}")
            if path.suffix == ".npy" and pts.dtype != np.float64:
                fail(msgs, cid, "npy not float64")
            A, b, p = check_code(truth, cid, msgs, dim=case["dim"])
            # the truth maps the clean cloud into itself: check on a fresh sample from it
            ext = np.ptp(pts, axis=0).max()
            rng = np.random.default_rng(0)
            x = pts[rng.choice(len(pts), 500)]
            y = np.einsum("kij,nj->nki", A, x) + b[None]
            # the images of the cloud's points lie near the cloud (outliers excepted)
            sub = pts[rng.choice(len(pts), 3000)]
            d = np.min(np.linalg.norm(y.reshape(-1, case["dim"])[:, None, :] - sub[None, ::3, :], axis=2), axis=1)
            near = np.mean(d < 0.05 * ext)
            stats.setdefault(case["family"], []).append(near)
            if near < 0.9:
                fail(msgs, cid, f"only {near:.2f} of the images of cloud points lie near the cloud")
            continue
        img = Image.open(path)
        img.load()
        W, H = img.size
        if (W, H) != (v["width"], v["height"]):
            fail(msgs, cid, f"size {img.size} vs {v['width']}x{v['height']}")
        if img.mode != v["mode"]:
            fail(msgs, cid, f"mode {img.mode} vs {v['mode']}")
        if (path.suffix == ".jpg") != (v["format"] == "jpeg") or (img.format == "JPEG") != (v["format"] == "jpeg"):
            fail(msgs, cid, "format")
        if case["front_end"] not in ("invert", "sdf"):
            if np.asarray(img).std() < 1:
                fail(msgs, cid, "flat picture")
            continue
        if case["front_end"] == "invert":
            A, b, p = check_code(truth, cid, msgs, dim=2)
            mask, outside = truth_code_mask(A, b, p, case["window"], W, H)
            tol = 1
        else:
            P, maps, base = check_pattern(truth, cid, msgs)
            mask, outside = truth_pattern_mask(P, maps, base, case["depth"], case["window"], W, H)
            tol = 1 + (v.get("line_width") or 0) / 2
        if outside > 0:
            fail(msgs, cid, f"{outside:.4f} of the truth lies outside the canvas")
        f = figureness(img, v)
        pic_lo, pic_hi = f > 0.3, f > 0.5
        recall = (dilate(pic_lo, 1) & mask).sum() / max(mask.sum(), 1)
        precision = (pic_hi & dilate(mask, math.ceil(tol))).sum() / max(pic_hi.sum(), 1)
        need = 0.85 if v["longer_side"] <= 64 else 0.9
        stats.setdefault(case["family"], []).append(min(recall, precision))
        if recall < need or precision < need:
            fail(msgs, cid, f"truth vs picture: recall {recall:.3f} precision {precision:.3f}")
        if overlays:
            ov = np.zeros((H, W, 3), np.uint8)
            ov[pic_hi] = (0, 200, 0)
            ov[mask] = (220, 0, 220)
            ov[pic_hi & mask] = (255, 255, 255)
            overlays_by_fam.setdefault(case["family"], []).append(
                (cid, Image.fromarray(ov), recall, precision))
    if overlays:
        out = out_root / "checks" / split_dir.name
        out.mkdir(parents=True, exist_ok=True)
        font = ImageFont.load_default()
        for fam, items in overlays_by_fam.items():
            cell, cols = 220, 6
            rows_n = -(-len(items) // cols)
            sheet = Image.new("RGB", (cols * cell, rows_n * (cell + 16)), (60, 60, 60))
            dr = ImageDraw.Draw(sheet)
            for k, (cid, im, r, pr) in enumerate(items):
                f = (cell - 10) / max(im.size)
                im = im.resize((max(1, round(im.width * f)), max(1, round(im.height * f))),
                               Image.Resampling.NEAREST if f > 1 else Image.Resampling.BOX)
                x0, y0 = (k % cols) * cell, (k // cols) * (cell + 16)
                sheet.paste(im, (x0 + 5, y0 + 5))
                dr.text((x0 + 4, y0 + cell), f"{cid} r{r:.2f} p{pr:.2f}", fill=(255, 255, 0), font=font)
            sheet.save(out / f"overlay_{fam}.png")
    return msgs, rows, stats


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("outdir", nargs="?", type=Path, default=HERE / "inputs")
    ap.add_argument("--overlays", action="store_true")
    a = ap.parse_args()
    bad = 0
    ids = {}
    for split in ["tune", "tune2", "test"]:
        d = a.outdir / split
        if not (d / "manifest.json").exists():
            continue
        msgs, rows, stats = check_split(d, a.overlays, a.outdir)
        man = json.loads((d / "manifest.json").read_text())
        ids[split] = man
        counts = Counter(c["family"] for c in man["cases"])
        print(f"{split}: {len(man['cases'])} cases " + ", ".join(f"{k} {n}" for k, n in counts.items()))
        for fam, key, val in rows:
            print(f"  {fam:16s} {key:12s} {val}")
        for fam, s in stats.items():
            print(f"  {fam:16s} worst agreement {min(s):.3f}  mean {np.mean(s):.3f}")
        for m in msgs:
            print("  FAIL", m)
        bad += len(msgs)
    # Every pair of splits present is disjoint: seeds, random truths, photo crops.
    seeds = lambda m: {tuple(c["seed"]) for c in m["cases"]}
    crops = lambda m: {(c["source"], tuple(c["crop"])) for c in m["cases"] if c["family"] == "photos"}

    def truths(split, m):
        out = set()
        for c in m["cases"]:
            if c["truth"] and c["family"] != "codes_classic":
                doc = json.loads((a.outdir / split / c["truth"]).read_text())
                doc.pop("name"), doc.pop("meta", None)
                out.add(json.dumps(doc, sort_keys=True))
        return out

    names = list(ids)
    for i, x in enumerate(names):
        for y in names[i + 1 :]:
            if seeds(ids[x]) & seeds(ids[y]):
                print(f"  FAIL seeds shared between {x} and {y}")
                bad += 1
            shared = len(truths(x, ids[x]) & truths(y, ids[y]))
            if shared:
                print(f"  FAIL {shared} truths shared between {x} and {y}")
                bad += 1
            if crops(ids[x]) & crops(ids[y]):
                print(f"  FAIL photo crops shared between {x} and {y}")
                bad += 1
    print("OK" if bad == 0 else f"{bad} problems")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
