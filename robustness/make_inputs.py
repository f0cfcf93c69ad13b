#!/usr/bin/env python3
"""Inputs of the "what users bring" robustness suite of ifslab's four inversion front-ends.

    python3 make_inputs.py --split tune|test|all -o OUTDIR [--preview]

Writes OUTDIR/<split>/manifest.json and the files it lists:
OUTDIR/<split>/<family>/<id>.<png|jpg|csv|npy> and, where a truth exists,
OUTDIR/<split>/<family>/<id>.truth.json (an ifslab-code/1 or ifslab-pattern/1 file).

This program is independent of ifslab on purpose: it shares no code with ifslab's renderers
(NumPy and Pillow only; it reads no ifslab file at run time). ifslab's sources were read for
the two file formats only. Everything is deterministic: every case draws its numbers from
its own NumPy SeedSequence (base seed, split, family, case index), and the tune and test
splits never share a seed, a random code, a perturbed pattern, a shape layout or a photo crop
(the classic published codes are shared, never their variation draw).

Families (see README.md): codes_random, codes_classic (-> `ifslab invert`), patterns_koch,
patterns_carpet (-> `ifslab sdf fit`), shapes, photos (-> `ifslab flame learn`), points2d,
points3d (-> `ifslab fit-points`).

Picture conventions: the y axis of a truth's coordinates points *up* in the picture. For the
code and pattern families the manifest records the window of truth coordinates the whole
canvas shows (`window`: min = lower-left corner, max = upper-right corner; pixels are square,
`pixel` units wide), so a scorer can draw the truth over the picture.
"""

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont
from PIL import __version__ as PILLOW_VERSION

BASE_SEED = 20251127
SPLIT_IDS = {"tune": 1, "test": 2, "tune2": 3, "tune3": 4, "tune4": 5}  # tune2..tune4: more tuning cases, never reported
FAMILIES = [
    "codes_random",
    "codes_classic",
    "patterns_koch",
    "patterns_carpet",
    "shapes",
    "photos",
    "points2d",
    "points3d",
]
FRONT_END = {
    "codes_random": "invert",
    "codes_classic": "invert",
    "patterns_koch": "sdf",
    "patterns_carpet": "sdf",
    "shapes": "flame",
    "photos": "flame",
    "points2d": "points",
    "points3d": "points",
}
CASES_PER_FAMILY = 24
HERE = Path(__file__).resolve().parent
REPO = HERE.parent


# --------------------------------------------------------------------------------------
# Seeds and balanced draws
# --------------------------------------------------------------------------------------


def rng_for(split, family, index, salt=0):
    """The generator of one case (index >= 0) or of a family's split-level draws (index -1)."""
    seq = np.random.SeedSequence(
        [BASE_SEED, SPLIT_IDS[split], FAMILIES.index(family), index + 1, salt]
    )
    return np.random.default_rng(seq)


def case_seed(split, family, index):
    """A number naming the case's seed sequence in the manifest."""
    return [BASE_SEED, SPLIT_IDS[split], FAMILIES.index(family), index + 1]


def balanced(rng, values, n, weights=None):
    """n draws in which each value occurs in proportion to its weight (rounded), shuffled."""
    k = len(values)
    w = np.ones(k) / k if weights is None else np.asarray(weights, float) / np.sum(weights)
    exact = w * n
    counts = np.floor(exact).astype(int)
    rest = n - counts.sum()
    order = np.argsort(-(exact - counts), kind="stable")
    counts[order[:rest]] += 1
    out = [v for v, c in zip(values, counts) for _ in range(c)]
    perm = rng.permutation(n)
    return [out[i] for i in perm]


def size_pool(rng, n):
    """Longer sides: two at 64, two at 1024, the rest stratified log-uniform in 128..512."""
    n_mid = n - 4
    u = (np.arange(n_mid) + rng.random(n_mid)) / n_mid
    mid = [int(2 * round(128 * 4 ** x / 2)) for x in u]
    out = [64, 64, 1024, 1024] + mid
    perm = rng.permutation(n)
    return [out[i] for i in perm]


def canvas_dims(rng, longer, kind):
    if kind == "square":
        return longer, longer, 1.0
    a = float(rng.uniform(1.2, 2.0))
    shorter = max(16, int(round(longer / a)))
    if kind == "landscape":
        return longer, shorter, a
    return shorter, longer, a


def draw_picture_variations(rng, n, modes=("L", "RGB", "RGBA")):
    """One variation dict per case: every value of every variation several times per split."""
    polarity = balanced(rng, ["bright-on-dark", "dark-on-light"], n)
    mode = balanced(rng, list(modes), n)
    framing = balanced(rng, ["centred-large", "offcentre-small"], n)
    canvas = balanced(rng, ["square", "landscape", "portrait"], n)
    sizes = size_pool(rng, n)
    flat = [i for i in range(n) if mode[i] != "RGBA"]
    fmt_flat = balanced(rng, ["png", "jpeg"], len(flat))
    noise_flat = balanced(rng, [True, False], len(flat), weights=[0.4, 0.6])
    alpha_idx = [i for i in range(n) if mode[i] == "RGBA"]
    under = balanced(rng, ["fg", "black"], len(alpha_idx))
    out = []
    for i in range(n):
        v = {
            "polarity": polarity[i],
            "mode": mode[i],
            "format": "png",
            "jpeg_quality": None,
            "noise": 0.0,
            "framing": framing[i],
            "canvas": canvas[i],
            "longer_side": sizes[i],
        }
        if sizes[i] <= 64:
            # A 64-pixel picture with the figure at 20-40 % of its side is a smudge: tiny
            # pictures keep the figure large.
            v["framing"] = "centred-large"
        if i in flat:
            j = flat.index(i)
            v["format"] = fmt_flat[j]
            v["_noisy"] = noise_flat[j]
        else:
            v["transparent_rgb"] = under[alpha_idx.index(i)]
        out.append(v)
    return out


def resolve_variation(rng, v):
    """Draws the case's own numbers (canvas, quality, noise, colours) into v."""
    w, h, aspect = canvas_dims(rng, v["longer_side"], v["canvas"])
    v["width"], v["height"], v["aspect"] = w, h, round(aspect, 4)
    if v["format"] == "jpeg":
        v["jpeg_quality"] = int(rng.integers(60, 91))
    if v.pop("_noisy", False):
        v["noise"] = round(float(rng.uniform(0.02, 0.06)), 4)
    return v


# --------------------------------------------------------------------------------------
# Colours and the last steps every picture takes
# --------------------------------------------------------------------------------------


def luma(rgb):
    rgb = np.asarray(rgb, float)
    return float(0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2])


def random_colour(rng, lo, hi, pastel=0.0):
    """A colour (floats in [0, 1]) with Rec. 601 luma in [lo, hi]; pastel mixes in white."""
    for _ in range(10000):
        c = rng.random(3)
        c = (1 - pastel) * c + pastel
        if lo <= luma(c) <= hi:
            return c
    raise RuntimeError("no colour in the luma range")


def hexc(c):
    c = np.clip(np.round(np.asarray(c) * 255), 0, 255).astype(int)
    return "#%02x%02x%02x" % tuple(c)


def pick_two_tone(rng, v):
    """Figure and background colours for the polarity and mode; recorded in v."""
    dark_fig = v["polarity"] == "dark-on-light"
    if v["mode"] == "L":
        if dark_fig:
            fg, bg = rng.uniform(0.0, 0.25), rng.uniform(0.8, 1.0)
        else:
            fg, bg = rng.uniform(0.75, 1.0), rng.uniform(0.0, 0.2)
        v["fg"], v["bg"] = round(float(fg), 4), round(float(bg), 4)
        return np.array([fg]), np.array([bg])
    if dark_fig:
        fg = random_colour(rng, 0.02, 0.33)
        bg = random_colour(rng, 0.78, 0.99, pastel=0.55)
    else:
        fg = random_colour(rng, 0.66, 1.0, pastel=0.25)
        bg = random_colour(rng, 0.0, 0.22)
    assert abs(luma(fg) - luma(bg)) >= 0.35
    v["fg"] = hexc(fg)
    v["bg"] = None if v["mode"] == "RGBA" else hexc(bg)
    return fg, bg


def coverage_to_image(rng, cov, v):
    """An anti-aliased coverage map (H×W in [0, 1]) as the case's picture."""
    fg, bg = pick_two_tone(rng, v)
    if v["mode"] == "RGBA":
        rgb = np.broadcast_to(fg, cov.shape + (3,)).copy()
        if v["transparent_rgb"] == "black":
            rgb[cov <= 0] = 0.0
        arr = np.concatenate([rgb, cov[..., None]], axis=2)
    else:
        arr = bg + cov[..., None] * (fg - bg)
    return finish_array(rng, arr, v)


def finish_array(rng, arr, v):
    """Noise (not on RGBA), clip, 8-bit quantisation, Pillow image of the case's mode."""
    if v["noise"] > 0 and v["mode"] != "RGBA":
        arr = arr + rng.normal(0.0, v["noise"], arr.shape)
    arr = np.clip(np.round(np.clip(arr, 0, 1) * 255), 0, 255).astype(np.uint8)
    if v["mode"] == "L":
        return Image.fromarray(arr[..., 0] if arr.ndim == 3 else arr, "L")
    return Image.fromarray(arr, v["mode"])


def save_picture(img, path_stem, v):
    if v["format"] == "jpeg":
        assert img.mode in ("L", "RGB")
        path = path_stem.with_suffix(".jpg")
        img.save(path, "JPEG", quality=v["jpeg_quality"])
    else:
        path = path_stem.with_suffix(".png")
        img.save(path, "PNG")
    return path


# --------------------------------------------------------------------------------------
# Framing: where the figure's bounding box goes on the canvas
# --------------------------------------------------------------------------------------


def place(rng, bbox, v, pad_px=0.0):
    """Scale and position for a figure with bounding box (x0, y0, x1, y1), y up.

    Returns (x_left, y_top, scale): canvas pixel (u, v) = ((x − x_left)·scale,
    (y_top − y)·scale). Large framing: the box's longer side 60–90 % of the canvas's shorter
    side, centred (±2 %). Small: 20–40 %, in a corner region away from the centre. pad_px is
    room kept around the box (half a line's width)."""
    W, H = v["width"], v["height"]
    bx0, by0, bx1, by1 = bbox
    bw, bh = bx1 - bx0, by1 - by0
    short = min(W, H)
    large = v["framing"] == "centred-large"
    frac = rng.uniform(0.6, 0.9) if large else rng.uniform(0.2, 0.4)
    scale = max(frac * short - 2 * pad_px, 1.0) / max(bw, bh)
    pw, ph = bw * scale + 2 * pad_px, bh * scale + 2 * pad_px
    if large:
        jx, jy = rng.uniform(-0.02, 0.02, 2) * short
        left = np.clip((W - pw) / 2 + jx, 0, W - pw)
        top = np.clip((H - ph) / 2 + jy, 0, H - ph)
    else:
        margin = 0.04 * short
        ux = rng.uniform(0.0, 0.22) if rng.random() < 0.5 else rng.uniform(0.78, 1.0)
        uy = rng.uniform(0.0, 0.22) if rng.random() < 0.5 else rng.uniform(0.78, 1.0)
        left = margin + ux * max(W - pw - 2 * margin, 0)
        top = margin + uy * max(H - ph - 2 * margin, 0)
    x_left = bx0 - (left + pad_px) / scale
    y_top = by1 + (top + pad_px) / scale
    v["figure_fraction"] = round(float(frac), 4)
    v["figure_centre"] = [
        round(float((left + pw / 2) / W), 4),
        round(float((top + ph / 2) / H), 4),
    ]
    return float(x_left), float(y_top), float(scale)


def window_of(x_left, y_top, scale, W, H):
    return {
        "min": [x_left, y_top - H / scale],
        "max": [x_left + W / scale, y_top],
        "pixel": 1.0 / scale,
        "y_up": True,
    }


# --------------------------------------------------------------------------------------
# Chaos game (any dimension) and coverage rendering
# --------------------------------------------------------------------------------------


def det_probabilities(A, floor=0.01):
    d = np.abs(np.linalg.det(A))
    p = d / d.sum() if d.sum() > 0 else np.ones(len(A)) / len(A)
    p = np.maximum(p, floor)
    return p / p.sum()


def fixed_point(A, b):
    return np.linalg.solve(np.eye(A.shape[0]) - A, b)


def chaos_game(rng, A, b, p, n_points, burn=20, n_traj=65536):
    """n_points points of the attractor: n_traj trajectories started at the fixed point of
    map 0 (on the attractor), the first `burn` steps dropped. float64 (n, dim)."""
    n_maps, dim, _ = A.shape
    n_traj = int(min(n_traj, max(256, n_points // 16)))
    steps = -(-n_points // n_traj)
    cum = np.cumsum(p)
    cum[-1] = 1.0
    x = np.tile(fixed_point(A[0], b[0]), (n_traj, 1))
    out = np.empty((steps * n_traj, dim), np.float64)
    comps = [[A[:, r, c] for c in range(dim)] for r in range(dim)]
    for s in range(burn + steps):
        idx = np.searchsorted(cum, rng.random(n_traj), side="right")
        np.minimum(idx, n_maps - 1, out=idx)
        nx = np.empty_like(x)
        for r in range(dim):
            acc = b[idx, r].copy()
            for c in range(dim):
                acc += comps[r][c][idx] * x[:, c]
            nx[:, r] = acc
        x = nx
        if s >= burn:
            k = s - burn
            out[k * n_traj:(k + 1) * n_traj] = x
    return out[:n_points]


def coverage(pts, x_left, y_top, scale, W, H, ss):
    """Binary coverage on an ss×ss supersampled grid averaged down: H×W floats in [0, 1]."""
    gx = np.floor((pts[:, 0] - x_left) * scale * ss).astype(np.int64)
    gy = np.floor((y_top - pts[:, 1]) * scale * ss).astype(np.int64)
    ok = (gx >= 0) & (gx < W * ss) & (gy >= 0) & (gy < H * ss)
    grid = np.zeros(H * ss * W * ss, np.uint8)
    grid[gy[ok] * (W * ss) + gx[ok]] = 1
    return grid.reshape(H, ss, W, ss).mean(axis=(1, 3), dtype=np.float32).astype(np.float64)


def n_points_for(longer):
    """2 M points at 128 px and below, 8 M at 1024, linear in the side between."""
    t = np.clip((longer - 128) / (1024 - 128), 0, 1)
    return int(2_000_000 + t * 6_000_000)


def supersample_for(longer):
    return 4 if longer <= 512 else 2


def code_stats(pts):
    """Bounding box, its aspect and how much of it a 256² framing covers."""
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    bw, bh = hi - lo
    aspect = max(bw, bh) / max(min(bw, bh), 1e-12)
    s = 255.0 / max(bw, bh)
    gx = np.clip(np.floor((pts[:, 0] - lo[0]) * s).astype(int), 0, 255)
    gy = np.clip(np.floor((pts[:, 1] - lo[1]) * s).astype(int), 0, 255)
    grid = np.zeros((256, 256), bool)
    grid[gy, gx] = True
    box_px = (math.floor(bh * s) + 1) * (math.floor(bw * s) + 1)
    fill = grid.sum() / box_px
    canvas_fill = grid.sum() / 256.0 ** 2
    return (lo, hi), float(aspect), float(fill), float(canvas_fill)


def code_json(name, A, b, p, meta):
    for i, M in enumerate(A):
        smax = np.linalg.svd(M, compute_uv=False)[0]
        if not smax < 1.0:
            raise ValueError(f"{name}: map {i} is not contractive (sigma_max {smax})")
    assert abs(np.sum(p) - 1.0) < 1e-12 and np.all(p >= 0)
    return {
        "format": "ifslab-code/1",
        "name": name,
        "dim": int(A.shape[1]),
        "maps": [
            {"matrix": [[float(x) for x in row] for row in M], "offset": [float(x) for x in t]}
            for M, t in zip(A, b)
        ],
        "probabilities": [float(x) for x in p],
        "meta": meta,
    }


def write_json(path, doc):
    path.write_text(json.dumps(doc, indent=2) + "\n")


# --------------------------------------------------------------------------------------
# Family 1: random affine codes (Anderson & Farrell's σ-factor rule)
# --------------------------------------------------------------------------------------


def rot(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s], [s, c]])


def sample_af_code(rng, n):
    """n random affine maps. Anderson & Farrell (WACV 2022) draw the singular values so the
    σ-factor Σ (σ1 + 2·σ2) lies in [(5 + n)/2, (6 + n)/2]; each matrix is
    R(θ)·diag(σ1, σ2)·R(φ) (times a reflection diag(1, −1) with probability 1/2), the
    translation uniform in [−1, 1]²."""
    alpha = rng.uniform((5 + n) / 2, (6 + n) / 2)
    while True:
        s1 = rng.uniform(0.2, 1.0, n)
        r = rng.uniform(0.15, 1.0, n)
        s2 = r * s1
        k = alpha / np.sum(s1 + 2 * s2)
        s1, s2 = s1 * k, s2 * k
        if s1.max() < 0.97:
            break
    A = np.empty((n, 2, 2))
    for i in range(n):
        refl = np.diag([1.0, -1.0]) if rng.random() < 0.5 else np.eye(2)
        A[i] = rot(rng.uniform(0, 2 * np.pi)) @ np.diag([s1[i], s2[i]]) @ rot(rng.uniform(0, 2 * np.pi)) @ refl
    b = rng.uniform(-1, 1, (n, 2))
    return A, b, float(alpha)


def gen_codes_random(split, outdir, n):
    fam = "codes_random"
    frng = rng_for(split, fam, -1)
    maps_pool = [2] + [3] * 4 + [4] * 4 + [5] * 3 + [6] * 3 + [7] * 3 + [8] * 2 + [9] * 2 + [10] * 2
    maps_pool = (maps_pool * (n // len(maps_pool) + 1))[:n]
    maps_pool = [maps_pool[i] for i in frng.permutation(n)]
    vars_ = draw_picture_variations(frng, n)
    cases = []
    for i in range(n):
        rng = rng_for(split, fam, i)
        N = maps_pool[i]
        tries = 0
        while True:
            tries += 1
            A, b, alpha = sample_af_code(rng, N)
            p = det_probabilities(A)
            pts = chaos_game(rng, A, b, p, 300_000, n_traj=4096)
            if not np.all(np.isfinite(pts)):
                continue
            (lo, hi), aspect, fill, _ = code_stats(pts)
            if aspect <= 6.0 and 0.05 <= fill <= 0.7:
                break
        cid = f"{fam}-{i:02d}"
        v = resolve_variation(rng, vars_[i])
        case = render_code_case(rng, split, outdir, fam, cid, A, b, p, v)
        meta = {
            "source": "Anderson-Farrell sigma-factor sampler (robustness/make_inputs.py)",
            "sigma_factor": alpha,
        }
        write_json(outdir / fam / f"{cid}.truth.json", code_json(cid, A, b, p, meta))
        case.update(
            {
                "maps": N,
                "sigma_factor": round(alpha, 6),
                "sum_abs_det": round(float(np.abs(np.linalg.det(A)).sum()), 6),
                "bbox_aspect": round(aspect, 4),
                "bbox_fill": round(fill, 4),
                "draws_rejected": tries - 1,
                "seed": case_seed(split, fam, i),
            }
        )
        cases.append(case)
    return cases


def render_code_case(rng, split, outdir, fam, cid, A, b, p, v):
    W, H = v["width"], v["height"]
    pts = chaos_game(rng, A, b, p, n_points_for(v["longer_side"]))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    x_left, y_top, scale = place(rng, (lo[0], lo[1], hi[0], hi[1]), v)
    cov = coverage(pts, x_left, y_top, scale, W, H, supersample_for(v["longer_side"]))
    img = coverage_to_image(rng, cov, v)
    path = save_picture(img, outdir / fam / cid, v)
    return {
        "id": cid,
        "family": fam,
        "front_end": FRONT_END[fam],
        "file": f"{fam}/{path.name}",
        "truth": f"{fam}/{cid}.truth.json",
        "window": window_of(x_left, y_top, scale, W, H),
        "variations": public_variations(v),
    }


def public_variations(v):
    keys = [
        "polarity", "mode", "format", "jpeg_quality", "noise", "framing", "canvas", "width",
        "height", "aspect", "longer_side", "figure_fraction", "figure_centre", "fg", "bg",
        "transparent_rgb", "line", "line_width",
    ]
    out = {k: v.get(k) for k in keys if k in v}
    out.setdefault("line", None)
    return out


# --------------------------------------------------------------------------------------
# Family 2: classic published codes
# --------------------------------------------------------------------------------------

S3 = math.sqrt(3.0)
# Rows (a, b, c, d, e, f): x' = a·x + b·y + e, y' = c·x + d·y + f.
CLASSIC_CODES = {
    # M. Barnsley, Fractals Everywhere (1988), the fern; also Fractint's fractint.ifs "fern".
    "barnsley_fern": [
        (0.0, 0.0, 0.0, 0.16, 0.0, 0.0),
        (0.85, 0.04, -0.04, 0.85, 0.0, 1.6),
        (0.2, -0.26, 0.23, 0.22, 0.0, 1.6),
        (-0.15, 0.28, 0.26, 0.24, 0.0, 0.44),
    ],
    # Sierpiński triangle: three half-size copies on the corners of an equilateral triangle.
    "sierpinski_triangle": [
        (0.5, 0.0, 0.0, 0.5, 0.0, 0.0),
        (0.5, 0.0, 0.0, 0.5, 0.5, 0.0),
        (0.5, 0.0, 0.0, 0.5, 0.25, S3 / 4),
    ],
    # Heighway dragon, f1(z) = (1+i)z/2, f2(z) = 1 − (1−i)z/2 (Wikipedia, "Dragon curve").
    "heighway_dragon": [
        (0.5, -0.5, 0.5, 0.5, 0.0, 0.0),
        (-0.5, -0.5, 0.5, -0.5, 1.0, 0.0),
    ],
    # Lévy C curve, f1(z) = (1−i)z/2, f2(z) = 1 + (1+i)(z−1)/2 (Wikipedia, "Lévy C curve").
    "levy_c_curve": [
        (0.5, 0.5, -0.5, 0.5, 0.0, 0.0),
        (0.5, -0.5, 0.5, 0.5, 0.5, -0.5),
    ],
    # Maple leaf, the four-map table of P. Bourke's "IFS" notes (paulbourke.net/fractals/ifs).
    "maple_leaf": [
        (0.14, 0.01, 0.0, 0.51, -0.08, -1.31),
        (0.43, 0.52, -0.45, 0.50, 1.49, -0.75),
        (0.45, -0.49, 0.47, 0.47, -1.62, -0.74),
        (0.49, 0.0, 0.0, 0.51, 0.02, 1.62),
    ],
    # Tree, Fractint's fractint.ifs "tree" (Stone Soup Group).
    "fractint_tree": [
        (0.0, 0.0, 0.0, 0.5, 0.0, 0.0),
        (0.42, -0.42, 0.42, 0.42, 0.0, 0.2),
        (0.42, 0.42, -0.42, 0.42, 0.0, 0.2),
        (0.1, 0.0, 0.0, 0.1, 0.0, 0.2),
    ],
    # Twin dragon (Davis & Knuth 1970): z ↦ (z + d)/(1 + i), d ∈ {0, 1}.
    "twin_dragon": [
        (0.5, 0.5, -0.5, 0.5, 0.0, 0.0),
        (0.5, 0.5, -0.5, 0.5, 0.5, -0.5),
    ],
    # Koch curve: four third-size copies, the middle two turned by ±60° (von Koch 1904).
    "koch_curve": [
        (1 / 3, 0.0, 0.0, 1 / 3, 0.0, 0.0),
        (1 / 6, -S3 / 6, S3 / 6, 1 / 6, 1 / 3, 0.0),
        (1 / 6, S3 / 6, -S3 / 6, 1 / 6, 0.5, S3 / 6),
        (1 / 3, 0.0, 0.0, 1 / 3, 2 / 3, 0.0),
    ],
    # Crystal ("cristal"), from Wegner, Tyler, Peterson & Branderhorst, Fractals for Windows
    # (1992), as typed in A. Schauber's Maple IFS procedures.
    "crystal": [
        (0.255, 0.0, 0.0, 0.255, 0.3726, 0.6714),
        (0.255, 0.0, 0.0, 0.255, 0.1146, 0.2232),
        (0.255, 0.0, 0.0, 0.255, 0.6306, 0.2232),
        (0.37, -0.642, 0.642, 0.37, 0.6356, -0.0061),
    ],
    # Spiral, Fractint's fractint.ifs "spiral".
    "fractint_spiral": [
        (0.787879, -0.424242, 0.242424, 0.859848, 1.758647, 1.408065),
        (-0.121212, 0.257576, 0.151515, 0.053030, -6.721654, 1.377236),
        (0.181818, -0.136364, 0.090909, 0.181818, 6.086107, 1.568035),
    ],
    # Dragon, Fractint's fractint.ifs "dragon" (not Heighway's).
    "fractint_dragon": [
        (0.824074, 0.281482, -0.212346, 0.864198, -1.882290, -0.110607),
        (0.088272, 0.520988, -0.463889, -0.377778, 0.785360, 8.095795),
    ],
    # Coral, Fractint's fractint.ifs "coral".
    "fractint_coral": [
        (0.307692, -0.531469, -0.461538, -0.293706, 5.401953, 8.655175),
        (0.307692, -0.076923, 0.153846, -0.447552, -1.295248, 4.152990),
        (0.0, 0.545455, 0.692308, -0.195804, -4.893637, 7.269794),
    ],
}


def classic_arrays(rows):
    A = np.array([[[r[0], r[1]], [r[2], r[3]]] for r in rows], float)
    b = np.array([[r[4], r[5]] for r in rows], float)
    return A, b


def gen_codes_classic(split, outdir, n):
    fam = "codes_classic"
    frng = rng_for(split, fam, -1)
    names = list(CLASSIC_CODES)
    pool = (names * (n // len(names) + 1))[:n]
    pool = [pool[i] for i in frng.permutation(n)]
    vars_ = draw_picture_variations(frng, n)
    cases = []
    for i in range(n):
        rng = rng_for(split, fam, i)
        name = pool[i]
        A, b = classic_arrays(CLASSIC_CODES[name])
        p = det_probabilities(A)
        cid = f"{fam}-{i:02d}"
        v = resolve_variation(rng, vars_[i])
        case = render_code_case(rng, split, outdir, fam, cid, A, b, p, v)
        meta = {"source": "published coefficients, see CLASSIC_CODES in robustness/make_inputs.py",
                "code": name}
        write_json(outdir / fam / f"{cid}.truth.json", code_json(name, A, b, p, meta))
        case.update({"maps": len(A), "code": name, "seed": case_seed(split, fam, i)})
        cases.append(case)
    return cases


# --------------------------------------------------------------------------------------
# Segment patterns (ifslab-pattern/1): maps between segments, words, drawing
# --------------------------------------------------------------------------------------


def seg_map(e1, e2, q1, q2):
    """The orientation-preserving similitude z ↦ w·z + t taking e1 → q1, e2 → q2 (complex)."""
    w = (q2 - q1) / (e2 - e1)
    return w, q1 - w * e1


def pattern_maps(P, pairs):
    return [seg_map(P[s0], P[s1], P[t0], P[t1]) for (s0, s1), (t0, t1) in pairs]


def koch_polyline(P, pairs, depth):
    """The depth-K Koch polyline: 4^K + 1 vertices (complex), p0 to p4."""
    maps = pattern_maps(P, pairs)
    line = np.array([P[0], P[4]])
    for _ in range(depth):
        parts = [maps[0][0] * line + maps[0][1]]
        parts += [w * line[1:] + t for (w, t) in maps[1:]]
        line = np.concatenate(parts)
    return line


def proper_crossings(line):
    """Number of pairs of non-adjacent polyline segments that cross properly."""
    a, b = line[:-1], line[1:]
    ax, ay, bx, by = a.real, a.imag, b.real, b.imag
    dx, dy = bx - ax, by - ay

    def cross(ux, uy, vx, vy):
        return ux * vy - uy * vx

    d1 = cross(dx[:, None], dy[:, None], ax[None, :] - ax[:, None], ay[None, :] - ay[:, None])
    d2 = cross(dx[:, None], dy[:, None], bx[None, :] - ax[:, None], by[None, :] - ay[:, None])
    d3 = cross(dx[None, :], dy[None, :], ax[:, None] - ax[None, :], ay[:, None] - ay[None, :])
    d4 = cross(dx[None, :], dy[None, :], bx[:, None] - ax[None, :], by[:, None] - ay[None, :])
    scale = np.abs(dx).max() + np.abs(dy).max()
    eps = 1e-12 * scale * scale
    hit = (d1 * d2 < -eps) & (d3 * d4 < -eps)
    n = len(a)
    i, j = np.indices((n, n))
    hit &= j > i + 1
    return int(hit.sum())


def pattern_json(name, P, pairs, base_kind, base_points, meta):
    for k, ((s0, s1), (t0, t1)) in enumerate(pairs):
        w, _ = seg_map(P[s0], P[s1], P[t0], P[t1])
        if not abs(w) < 1.0:
            raise ValueError(f"{name}: pair {k} is not contractive (scale {abs(w)})")
    return {
        "format": "ifslab-pattern/1",
        "name": name,
        "points": [[float(z.real), float(z.imag)] for z in P],
        "pairs": [{"source": [int(s0), int(s1)], "target": [int(t0), int(t1)]}
                  for (s0, s1), (t0, t1) in pairs],
        "base": {"kind": base_kind, "points": [int(base_points[0]), int(base_points[1])]},
        "meta": meta,
    }


KOCH_PAIRS = [((0, 4), (i, i + 1)) for i in range(4)]


def perturbed_koch(rng):
    """Koch points with the apex moved up/down and sideways, p1 and p3 along and off the
    line; every map's scale in [0.2, 0.6] and no proper self-crossing at depth 5."""
    h0 = S3 / 6
    while True:
        apex = complex(0.5 + rng.uniform(-0.1, 0.1), h0 * rng.uniform(0.6, 1.6))
        p1 = complex(1 / 3 + rng.uniform(-0.07, 0.07), rng.uniform(-0.06, 0.06))
        p3 = complex(2 / 3 + rng.uniform(-0.07, 0.07), rng.uniform(-0.06, 0.06))
        P = np.array([0j, p1, apex, p3, 1 + 0j])
        scales = [abs(w) for w, _ in pattern_maps(P, KOCH_PAIRS)]
        if max(scales) > 0.6 or min(scales) < 0.2:
            continue
        if proper_crossings(koch_polyline(P, KOCH_PAIRS, 5)) == 0:
            return P, scales


def to_canvas(z, x_left, y_top, scale, R):
    """Complex points → hi-res canvas pixel coordinates (R× the final resolution)."""
    u = (z.real - x_left) * scale * R
    v = (y_top - z.imag) * scale * R
    return u, v


def hires_factor(longer):
    return 8 if longer <= 512 else 4


def gen_patterns_koch(split, outdir, n):
    fam = "patterns_koch"
    frng = rng_for(split, fam, -1)
    vars_ = draw_picture_variations(frng, n)
    depths = balanced(frng, [5, 6], n)
    lines = balanced(frng, ["thin", "thick"], n)
    cases = []
    for i in range(n):
        rng = rng_for(split, fam, i)
        P, scales = perturbed_koch(rng)
        K = depths[i]
        v = resolve_variation(rng, vars_[i])
        v["line"] = lines[i]
        lw = 1.0 if lines[i] == "thin" else float(rng.uniform(2.5, 6.0))
        v["line_width"] = round(lw, 3)
        line = koch_polyline(P, KOCH_PAIRS, K)
        bbox = (line.real.min(), line.imag.min(), line.real.max(), line.imag.max())
        x_left, y_top, scale = place(rng, bbox, v, pad_px=lw / 2 + 1)
        W, H, R = v["width"], v["height"], hires_factor(v["longer_side"])
        if lines[i] == "thick":
            # a thick line stays a line: at most 1/20 of the figure's width (2.5 px at least)
            lw = min(lw, max(2.5, (bbox[2] - bbox[0]) * scale / 20))
            v["line_width"] = round(lw, 3)
        u, vv = to_canvas(line, x_left, y_top, scale, R)
        hi = Image.new("L", (W * R, H * R), 0)
        ImageDraw.Draw(hi).line(
            list(zip(u.tolist(), vv.tolist())), fill=255, width=max(1, int(round(lw * R))),
            joint="curve",
        )
        cov = np.asarray(hi.reduce(R), np.float64) / 255.0
        img = coverage_to_image(rng, cov, v)
        cid = f"{fam}-{i:02d}"
        path = save_picture(img, outdir / fam / cid, v)
        d0 = np.array([0, 1 / 3, 0.5 + 1j * S3 / 6, 2 / 3, 1])
        meta = {"depth": K, "pattern": "koch", "source": "perturbed Koch pattern (robustness/make_inputs.py)"}
        write_json(outdir / fam / f"{cid}.truth.json",
                   pattern_json(cid, P, KOCH_PAIRS, "segment", (0, 4), meta))
        cases.append(
            {
                "id": cid,
                "family": fam,
                "front_end": FRONT_END[fam],
                "file": f"{fam}/{path.name}",
                "truth": f"{fam}/{cid}.truth.json",
                "pattern": "koch",
                "depth": K,
                "map_scales": [round(s, 5) for s in scales],
                "apex_height_ratio": round(float(P[2].imag / (S3 / 6)), 4),
                "max_point_shift": round(float(np.abs(P - d0).max()), 5),
                "window": window_of(x_left, y_top, scale, W, H),
                "variations": public_variations(v),
                "seed": case_seed(split, fam, i),
            }
        )
    return cases


def pij(i, j):
    return (i - 1) * 4 + (j - 1)


CARPET_CELLS = [(1, 1), (1, 2), (1, 3), (2, 1), (2, 3), (3, 1), (3, 2), (3, 3)]
CARPET_PAIRS = [((pij(1, 1), pij(4, 4)), (pij(i, j), pij(i + 1, j + 1))) for i, j in CARPET_CELLS]


def perturbed_carpet(rng, global_transform):
    """The carpet-square grid jittered (up to 0.015–0.04 per coordinate), sometimes under a
    global rotation + shear about the centre; every map's scale below 0.6."""
    base = np.array([complex((j - 1) / 3, (i - 1) / 3) for i in range(1, 5) for j in range(1, 5)])
    while True:
        J = rng.uniform(0.015, 0.04)
        P = base + rng.uniform(-J, J, 16) + 1j * rng.uniform(-J, J, 16)
        info = {"jitter": round(float(J), 4), "rotation_deg": 0.0, "shear": 0.0}
        if global_transform:
            th = rng.uniform(-25, 25)
            k = rng.uniform(-0.25, 0.25)
            c = 0.5 + 0.5j
            z = P - c
            z = (z.real + k * z.imag) + 1j * z.imag
            P = c + z * np.exp(1j * np.radians(th))
            info.update(rotation_deg=round(float(th), 3), shear=round(float(k), 4))
        scales = [abs(w) for w, _ in pattern_maps(P, CARPET_PAIRS)]
        if max(scales) < 0.6:
            return P, scales, info


def carpet_squares(P, depth):
    """Corner arrays (4, n) of the leaf squares: the base square on the diagonal {p11, p44}
    under every word of length `depth`."""
    maps = pattern_maps(P, CARPET_PAIRS)
    w = np.array([1 + 0j])
    t = np.array([0j])
    for _ in range(depth):
        w = np.concatenate([wi * w for wi, _ in maps])
        t = np.concatenate([wi * t + ti for wi, ti in maps])
    a, b = w * P[0] + t, w * P[15] + t
    m, h = (a + b) / 2, 1j * (b - a) / 2
    return np.stack([a, m + h, b, m - h])


def gen_patterns_carpet(split, outdir, n):
    fam = "patterns_carpet"
    frng = rng_for(split, fam, -1)
    vars_ = draw_picture_variations(frng, n)
    depths = balanced(frng, [3, 4], n, weights=[0.75, 0.25])
    globals_ = balanced(frng, [True, False], n)
    cases = []
    for i in range(n):
        rng = rng_for(split, fam, i)
        P, scales, info = perturbed_carpet(rng, globals_[i])
        K = depths[i]
        v = resolve_variation(rng, vars_[i])
        sq = carpet_squares(P, K)
        bbox = (sq.real.min(), sq.imag.min(), sq.real.max(), sq.imag.max())
        x_left, y_top, scale = place(rng, bbox, v)
        W, H, R = v["width"], v["height"], hires_factor(v["longer_side"])
        u, vv = to_canvas(sq, x_left, y_top, scale, R)
        hi = Image.new("L", (W * R, H * R), 0)
        draw = ImageDraw.Draw(hi)
        for k in range(sq.shape[1]):
            draw.polygon([(u[c, k], vv[c, k]) for c in range(4)], fill=255)
        cov = np.asarray(hi.reduce(R), np.float64) / 255.0
        img = coverage_to_image(rng, cov, v)
        cid = f"{fam}-{i:02d}"
        path = save_picture(img, outdir / fam / cid, v)
        meta = {"depth": K, "pattern": "carpet-square",
                "source": "perturbed carpet-square pattern (robustness/make_inputs.py)"}
        write_json(outdir / fam / f"{cid}.truth.json",
                   pattern_json(cid, P, CARPET_PAIRS, "box", (pij(1, 1), pij(4, 4)), meta))
        cases.append(
            {
                "id": cid,
                "family": fam,
                "front_end": FRONT_END[fam],
                "file": f"{fam}/{path.name}",
                "truth": f"{fam}/{cid}.truth.json",
                "pattern": "carpet-square",
                "depth": K,
                "perturbation": info,
                "map_scales": [round(s, 5) for s in scales],
                "window": window_of(x_left, y_top, scale, W, H),
                "variations": public_variations(v),
                "seed": case_seed(split, fam, i),
            }
        )
    return cases


# --------------------------------------------------------------------------------------
# Family 5: flat-coloured shapes
# --------------------------------------------------------------------------------------


def shape_polygon(rng, kind, cx, cy, r):
    """Vertices (x, y) of one shape of radius about r around (cx, cy), y down."""
    th = rng.uniform(0, 2 * np.pi)
    if kind == "circle":
        ang, rx, ry, th = np.linspace(0, 2 * np.pi, 256, endpoint=False), r, r, 0.0
    elif kind == "ellipse":
        ang = np.linspace(0, 2 * np.pi, 256, endpoint=False)
        rx, ry = r, r * rng.uniform(0.35, 0.75)
    elif kind == "rectangle":
        e = rng.uniform(0.4, 0.9)
        ang = np.array([math.atan2(e, 1), math.pi - math.atan2(e, 1),
                        math.pi + math.atan2(e, 1), -math.atan2(e, 1)])
        rx = ry = r
        if rng.random() < 0.4:
            th = 0.0  # axis-aligned, as most drawn rectangles are
    elif kind == "triangle":
        ang = np.sort(rng.uniform(0, 2 * np.pi, 3))
        # keep it from being a sliver: vertices at least 70° apart
        while np.min(np.diff(np.concatenate([ang, ang[:1] + 2 * np.pi]))) < np.radians(70):
            ang = np.sort(rng.uniform(0, 2 * np.pi, 3))
        rx = ry = r
    else:  # regular polygon, 5–8 sides
        k = int(rng.integers(5, 9))
        ang = np.arange(k) * 2 * np.pi / k
        rx = ry = r
    x, y = rx * np.cos(ang), ry * np.sin(ang)
    c, s = math.cos(th), math.sin(th)
    return np.stack([cx + c * x - s * y, cy + s * x + c * y], axis=1)


def distinct_colours(rng, k, bg, min_luma_gap=0.2, min_dist=0.35):
    out = []
    for _ in range(100000):
        c = rng.random(3)
        # flat, fairly saturated colours
        if np.ptp(c) < 0.35 and rng.random() < 0.8:
            continue
        if abs(luma(c) - luma(bg)) < min_luma_gap:
            continue
        if any(np.linalg.norm(c - o) < min_dist for o in out):
            continue
        out.append(c)
        if len(out) == k:
            return out
    raise RuntimeError("no distinct colours")


def gen_shapes(split, outdir, n):
    fam = "shapes"
    frng = rng_for(split, fam, -1)
    vars_ = draw_picture_variations(frng, n)
    backgrounds = balanced(frng, ["white", "black", "colour"], n)
    counts = balanced(frng, [2, 3, 4, 5], n)
    kinds_all = ["circle", "ellipse", "rectangle", "triangle", "polygon"]
    cases = []
    for i in range(n):
        rng = rng_for(split, fam, i)
        v = resolve_variation(rng, vars_[i])
        v.pop("polarity")
        v.pop("transparent_rgb", None)
        W, H = v["width"], v["height"]
        ss = supersample_for(v["longer_side"])
        bgk = backgrounds[i]
        bg = {"white": np.ones(3), "black": np.zeros(3)}.get(bgk)
        if bg is None:
            bg = random_colour(rng, 0.1, 0.9, pastel=rng.uniform(0, 0.6))
        k = counts[i]
        cols = distinct_colours(rng, k, bg)
        kinds = [kinds_all[j] for j in rng.choice(5, k, replace=k > 5)]
        # the composition's box (framing), then shapes inside it
        short = min(W, H)
        frac = rng.uniform(0.6, 0.9) if v["framing"] == "centred-large" else rng.uniform(0.25, 0.45)
        bw = bh = frac * short
        if v["framing"] == "centred-large":
            # a composition may use the long side too
            if W > H:
                bw = min(W * rng.uniform(0.6, 0.9), W - 0.1 * short)
            elif H > W:
                bh = min(H * rng.uniform(0.6, 0.9), H - 0.1 * short)
            left, top = (W - bw) / 2, (H - bh) / 2
        else:
            margin = 0.04 * short
            ux = rng.uniform(0.0, 0.2) if rng.random() < 0.5 else rng.uniform(0.8, 1.0)
            uy = rng.uniform(0.0, 0.2) if rng.random() < 0.5 else rng.uniform(0.8, 1.0)
            left = margin + ux * (W - bw - 2 * margin)
            top = margin + uy * (H - bh - 2 * margin)
        v["figure_fraction"] = round(float(frac), 4)
        v["figure_centre"] = [round(float((left + bw / 2) / W), 4), round(float((top + bh / 2) / H), 4)]
        hi_rgb = Image.new("RGB", (W * ss, H * ss), tuple(int(round(x * 255)) for x in bg))
        hi_a = Image.new("L", (W * ss, H * ss), 0)
        d_rgb, d_a = ImageDraw.Draw(hi_rgb), ImageDraw.Draw(hi_a)
        shapes = []
        placed = []
        for j in range(k):
            # shapes may overlap a little but not hide one another: centres at least
            # 0.8·(r_i + r_j) apart where 60 tries allow it
            for _ in range(60):
                r = rng.uniform(0.14, 0.32) * min(bw, bh)
                cx = left + rng.uniform(r, bw - r) if bw > 2 * r else left + bw / 2
                cy = top + rng.uniform(r, bh - r) if bh > 2 * r else top + bh / 2
                if all(math.hypot(cx - qx, cy - qy) >= 0.8 * (r + qr) for qx, qy, qr in placed):
                    break
            placed.append((cx, cy, r))
            poly = shape_polygon(rng, kinds[j], cx, cy, r)
            # inside the canvas, whatever the rotation
            poly[:, 0] = np.clip(poly[:, 0], 1, W - 1)
            poly[:, 1] = np.clip(poly[:, 1], 1, H - 1)
            pts = [(float(x * ss), float(y * ss)) for x, y in poly]
            fill = tuple(int(round(x * 255)) for x in cols[j])
            d_rgb.polygon(pts, fill=fill)
            d_a.polygon(pts, fill=255)
            shapes.append({"kind": kinds[j], "colour": hexc(cols[j]),
                           "centre": [round(float(cx / W), 4), round(float(cy / H), 4)],
                           "radius": round(float(r / short), 4)})
        rgb = np.asarray(hi_rgb, np.float32) / 255.0
        a = np.asarray(hi_a, np.float32) / 255.0
        if v["mode"] == "RGBA":
            # un-premultiplied average: edge pixels keep the shapes' colours
            pre = (rgb * a[..., None]).reshape(H, ss, W, ss, 3).mean(axis=(1, 3))
            al = a.reshape(H, ss, W, ss).mean(axis=(1, 3))
            col = np.where(al[..., None] > 0, pre / np.maximum(al[..., None], 1e-9), bg)
            arr = np.concatenate([col, al[..., None]], axis=2).astype(np.float64)
        else:
            arr = rgb.reshape(H, ss, W, ss, 3).mean(axis=(1, 3)).astype(np.float64)
            if v["mode"] == "L":
                arr = (0.299 * arr[..., 0] + 0.587 * arr[..., 1] + 0.114 * arr[..., 2])[..., None]
        img = finish_array(rng, arr, v)
        cid = f"{fam}-{i:02d}"
        path = save_picture(img, outdir / fam / cid, v)
        cases.append(
            {
                "id": cid,
                "family": fam,
                "front_end": FRONT_END[fam],
                "file": f"{fam}/{path.name}",
                "truth": None,
                "background": bgk,
                "background_rgb": hexc(bg),
                "n_shapes": k,
                "shapes": shapes,
                "variations": public_variations(v),
                "seed": case_seed(split, fam, i),
            }
        )
    return cases


# --------------------------------------------------------------------------------------
# Family 6: photos and paintings
# --------------------------------------------------------------------------------------

PHOTO_SOURCES = [
    "data/photos/astronaut.png",
    "data/photos/coffee.png",
    "data/photos/chelsea.png",
    "data/paintings/FightingForms.jpg",
    "data/paintings/Wisteria.jpg",
    "data/paintings/circles3.png",
]


def draw_crop(rng, sw, sh, aspect_wh):
    """A crop box (x0, y0, x1, y1) of aspect aspect_wh in an sw×sh source, 35–100 % of the
    largest such box."""
    if sw / sh > aspect_wh:
        mh, mw = sh, sh * aspect_wh
    else:
        mw, mh = sw, sw / aspect_wh
    f = rng.uniform(0.35, 1.0)
    cw, ch = mw * f, mh * f
    x0 = rng.uniform(0, sw - cw)
    y0 = rng.uniform(0, sh - ch)
    return (x0, y0, x0 + cw, y0 + ch)


def box_iou(a, b):
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    area = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / area


def photo_plan(split, n):
    """Sources, crops and variations of a split's photo cases (the test split's crops keep
    IoU ≤ 0.5 with every tune crop of the same source)."""
    fam = "photos"
    frng = rng_for(split, fam, -1)
    sources = balanced(frng, PHOTO_SOURCES, n)
    modes = balanced(frng, ["RGB", "L"], n, weights=[2, 1])
    fmts = balanced(frng, ["png", "jpeg"], n)
    canvas = balanced(frng, ["square", "landscape", "portrait"], n)
    n_mid = n - 3
    u = (np.arange(n_mid) + frng.random(n_mid)) / n_mid
    sizes = [64, 64, 512] + [int(2 * round(128 * 4 ** x / 2)) for x in u]
    sizes = [sizes[k] for k in frng.permutation(n)]
    plan = []
    for i in range(n):
        rng = rng_for(split, fam, i)
        v = {"mode": modes[i], "format": fmts[i], "jpeg_quality": None, "noise": 0.0,
             "canvas": canvas[i], "longer_side": sizes[i]}
        W, H, a = canvas_dims(rng, sizes[i], canvas[i])
        v.update(width=W, height=H, aspect=round(a, 4))
        if v["format"] == "jpeg":
            v["jpeg_quality"] = int(rng.integers(60, 91))
        plan.append((sources[i], v, rng))
    return plan


def gen_photos(split, outdir, n):
    fam = "photos"
    plan = photo_plan(split, n)
    avoid = {}
    if split == "test":
        for src, v, rng in photo_plan("tune", n):
            with Image.open(REPO / src) as im:
                sw, sh = im.size
            avoid.setdefault(src, []).append(draw_crop(rng, sw, sh, v["width"] / v["height"]))
    cases = []
    for i, (src, v, rng) in enumerate(plan):
        im = Image.open(REPO / src).convert("RGB")
        sw, sh = im.size
        for _ in range(1000):
            box = draw_crop(rng, sw, sh, v["width"] / v["height"])
            if all(box_iou(box, b) <= 0.5 for b in avoid.get(src, [])):
                break
        else:
            raise RuntimeError(f"no fresh crop of {src}")
        out = im.resize((v["width"], v["height"]), Image.Resampling.LANCZOS, box=box)
        if v["mode"] == "L":
            out = out.convert("L")
        cid = f"{fam}-{i:02d}"
        path = save_picture(out, outdir / fam / cid, v)
        cases.append(
            {
                "id": cid,
                "family": fam,
                "front_end": FRONT_END[fam],
                "file": f"{fam}/{path.name}",
                "truth": None,
                "source": src,
                "crop": [round(float(x), 2) for x in box],
                "crop_scale": round(float((box[2] - box[0]) * (box[3] - box[1]) / (sw * sh)), 4),
                "variations": dict(v),
                "seed": case_seed(split, fam, i),
            }
        )
    return cases


# --------------------------------------------------------------------------------------
# Families 7, 8: point clouds of random similitude codes
# --------------------------------------------------------------------------------------


def haar_rotation(rng, d):
    q, r = np.linalg.qr(rng.normal(size=(d, d)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def sample_similitudes(rng, k, dim):
    A = np.empty((k, dim, dim))
    info = []
    for i in range(k):
        s = rng.uniform(0.3, 0.55)
        refl = rng.random() < 0.5
        if dim == 2:
            Q = rot(rng.uniform(0, 2 * np.pi))
            D = np.diag([1.0, -1.0]) if refl else np.eye(2)
        else:
            Q = haar_rotation(rng, 3)
            D = np.diag([1.0, 1.0, -1.0]) if refl else np.eye(3)
        A[i] = s * Q @ D
        info.append({"scale": round(float(s), 5), "reflection": bool(refl)})
    b = rng.uniform(-1, 1, (k, dim))
    return A, b, info


def cloud_ok(A, b, pts):
    """Non-degenerate: the pieces f_i(A) lie apart (their centres at least 0.45 RMS radii
    from each other) and the cloud is not flat (smallest/largest principal spread ≥ 0.2)."""
    m = pts.mean(axis=0)
    rms = math.sqrt(((pts - m) ** 2).sum(axis=1).mean())
    centres = np.einsum("kij,j->ki", A, m) + b
    dmin = min(np.linalg.norm(centres[i] - centres[j])
               for i in range(len(A)) for j in range(i + 1, len(A)))
    ev = np.linalg.eigvalsh(np.cov((pts - m).T))
    flat = math.sqrt(max(ev[0], 0) / ev[-1])
    return dmin >= 0.45 * rms and flat >= 0.2, dmin / rms, flat


def gen_points(split, outdir, n, dim):
    fam = f"points{dim}d"
    frng = rng_for(split, fam, -1)
    ks = balanced(frng, [2, 3, 4, 5], n)
    kinds = balanced(frng, ["clean", "noise", "outliers", "noise+outliers"], n)
    fmts = balanced(frng, ["csv", "npy"], n)
    units = balanced(frng, ["unit", "scaled"], n)
    cases = []
    n_pts = 10_000
    for i in range(n):
        rng = rng_for(split, fam, i)
        k = ks[i]
        tries = 0
        while True:
            tries += 1
            A, b, info = sample_similitudes(rng, k, dim)
            p = np.array([m["scale"] ** dim for m in info])
            p = p / p.sum()
            pts = chaos_game(rng, A, b, p, 4000, burn=40, n_traj=400)
            ok, sep, flat = cloud_ok(A, b, pts)
            if ok:
                break
        n_out = int(round(0.01 * n_pts)) if "outliers" in kinds[i] else 0
        pts = chaos_game(rng, A, b, p, n_pts - n_out, burn=40, n_traj=500)
        # user units: y = c·x + d, the truth conjugated: y ↦ A y + (c·b + d − A d)
        if units[i] == "scaled":
            c = float(10 ** rng.uniform(-1.0, 2.5))
            d = rng.uniform(-1, 1, dim) * float(10 ** rng.uniform(0, 3))
        else:
            c, d = 1.0, np.zeros(dim)
        pts = c * pts + d
        bt = c * b + d - np.einsum("kij,j->ki", A, d)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        extent = float((hi - lo).max())
        sd = 0.0
        if "noise" in kinds[i]:
            sd = float(rng.uniform(0.005, 0.01))
            pts = pts + rng.normal(0, sd * extent, pts.shape)
        if n_out:
            ctr, half = (lo + hi) / 2, (hi - lo) / 2 * 1.2
            outl = ctr + rng.uniform(-1, 1, (n_out, dim)) * half
            pts = np.concatenate([pts, outl])
            pts = pts[rng.permutation(len(pts))]
        cid = f"{fam}-{i:02d}"
        if fmts[i] == "csv":
            path = outdir / fam / f"{cid}.csv"
            np.savetxt(path, pts, fmt="%.10g", delimiter=",")
        else:
            path = outdir / fam / f"{cid}.npy"
            np.save(path, pts.astype(np.float64))
        meta = {"source": "random similitudes (robustness/make_inputs.py)", "maps": info}
        write_json(outdir / fam / f"{cid}.truth.json", code_json(cid, A, bt, p, meta))
        cases.append(
            {
                "id": cid,
                "family": fam,
                "front_end": FRONT_END[fam],
                "file": f"{fam}/{path.name}",
                "truth": f"{fam}/{cid}.truth.json",
                "k": k,
                "dim": dim,
                "n_points": int(len(pts)),
                "piece_separation": round(float(sep), 4),
                "flatness": round(float(flat), 4),
                "draws_rejected": tries - 1,
                "variations": {
                    "format": fmts[i],
                    "noise": round(sd, 5),
                    "noise_of": "largest bounding-box side of the clean cloud",
                    "outliers": n_out / len(pts),
                    "outlier_box": "bounding box enlarged by 20 %" if n_out else None,
                    "units": units[i],
                    "units_scale": c,
                    "units_offset": [float(x) for x in d],
                },
                "seed": case_seed(split, fam, i),
            }
        )
    return cases


# --------------------------------------------------------------------------------------
# Contact sheets
# --------------------------------------------------------------------------------------


def checkerboard(w, h, cell=8):
    y, x = np.indices((h, w))
    c = np.where(((x // cell) + (y // cell)) % 2 == 0, 205, 235).astype(np.uint8)
    return Image.fromarray(np.stack([c, c, c], axis=2), "RGB")


def thumb_picture(path, box):
    im = Image.open(path)
    im.load()
    f = box / max(im.size)
    size = (max(1, round(im.width * f)), max(1, round(im.height * f)))
    # small pictures are blown up with visible pixels, large ones shrunk smoothly
    im = im.resize(size, Image.Resampling.NEAREST if f > 1 else Image.Resampling.LANCZOS)
    if im.mode in ("RGBA", "LA", "P"):
        im = im.convert("RGBA")
        bg = checkerboard(*im.size)
        bg.paste(im, (0, 0), im)
        return bg
    return im.convert("RGB")


def thumb_cloud(path, box):
    pts = np.load(path) if str(path).endswith(".npy") else np.loadtxt(path, delimiter=",")
    if pts.shape[1] == 3:
        # oblique view: azimuth 35°, elevation 25°
        az, el = np.radians(35), np.radians(25)
        Rz = np.array([[math.cos(az), -math.sin(az), 0], [math.sin(az), math.cos(az), 0], [0, 0, 1]])
        Rx = np.array([[1, 0, 0], [0, math.cos(el), -math.sin(el)], [0, math.sin(el), math.cos(el)]])
        q = pts @ (Rx @ Rz).T
        xy, depth = q[:, [0, 2]], q[:, 1]
    else:
        xy, depth = pts, np.zeros(len(pts))
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    s = (box - 8) / max((hi - lo).max(), 1e-12)
    u = ((xy[:, 0] - lo[0]) * s + 4 + (box - 8 - (hi[0] - lo[0]) * s) / 2).astype(int)
    v = (box - 5 - ((xy[:, 1] - lo[1]) * s + (box - 8 - (hi[1] - lo[1]) * s) / 2)).astype(int)
    img = np.full((box, box, 3), 255, np.uint8)
    if np.ptp(depth) > 0:
        shade = (40 + 150 * (depth - depth.min()) / np.ptp(depth)).astype(np.uint8)
    else:
        shade = np.full(len(pts), 30, np.uint8)
    order = np.argsort(-depth)
    u, v, shade = np.clip(u[order], 0, box - 1), np.clip(v[order], 0, box - 1), shade[order]
    img[v, u] = np.stack([shade, shade, np.minimum(shade + 60, 255)], axis=1)
    return Image.fromarray(img, "RGB")


def label_of(case):
    v = case.get("variations", {})
    bits = []
    if case["front_end"] == "points":
        bits = [f"k{case['k']}", v["format"], v["units"]]
        if v["noise"]:
            bits.append("noise")
        if v["outliers"]:
            bits.append("outl")
    else:
        bits = [v.get("mode", ""), "jpg" if v.get("format") == "jpeg" else "png", f"{v['width']}x{v['height']}"]
        if v.get("noise"):
            bits.append("noise")
        if case.get("depth"):
            bits.append(f"d{case['depth']}")
        if v.get("line"):
            bits.append(v["line"])
        if case.get("code"):
            bits.append(case["code"][:14])
        if "maps" in case and case["family"] == "codes_random":
            bits.append(f"N{case['maps']}")
    return " ".join(bits)


def contact_sheet(split_dir, family, cases, cell=200, cols=6):
    font = ImageFont.load_default()
    rows = -(-len(cases) // cols)
    lab = 28
    sheet = Image.new("RGB", (cols * cell, rows * (cell + lab)), (128, 128, 128))
    draw = ImageDraw.Draw(sheet)
    for k, case in enumerate(cases):
        path = split_dir / case["file"]
        th = thumb_cloud(path, cell - 10) if case["front_end"] == "points" else thumb_picture(path, cell - 10)
        x0, y0 = (k % cols) * cell, (k // cols) * (cell + lab)
        sheet.paste(th, (x0 + (cell - th.width) // 2, y0 + 4 + (cell - 10 - th.height) // 2))
        draw.text((x0 + 4, y0 + cell - 2), case["id"], fill=(255, 255, 255), font=font)
        draw.text((x0 + 4, y0 + cell + 11), label_of(case)[:34], fill=(230, 230, 160), font=font)
    out = split_dir / f"preview_{family}.png"
    sheet.save(out)
    return out


# --------------------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------------------

GENERATORS = {
    "codes_random": gen_codes_random,
    "codes_classic": gen_codes_classic,
    "patterns_koch": gen_patterns_koch,
    "patterns_carpet": gen_patterns_carpet,
    "shapes": gen_shapes,
    "photos": gen_photos,
    "points2d": lambda s, o, n: gen_points(s, o, n, 2),
    "points3d": lambda s, o, n: gen_points(s, o, n, 3),
}


def make_split(split, out_root, preview, families, n):
    split_dir = out_root / split
    split_dir.mkdir(parents=True, exist_ok=True)
    all_cases = []
    for fam in families:
        t0 = time.time()
        fam_dir = split_dir / fam
        fam_dir.mkdir(exist_ok=True)
        for old in fam_dir.iterdir():
            old.unlink()
        cases = GENERATORS[fam](split, split_dir, n)
        all_cases.extend(cases)
        print(f"  {split}/{fam}: {len(cases)} cases in {time.time() - t0:.1f} s", flush=True)
        if preview:
            contact_sheet(split_dir, fam, cases)
    ids = [c["id"] for c in all_cases]
    assert len(ids) == len(set(ids))
    manifest = {
        "split": split,
        "generator": {
            "script": "make_inputs.py",
            "numpy": np.__version__,
            "Pillow": PILLOW_VERSION,
            "python": sys.version.split()[0],
            "seed": BASE_SEED,
            "split_seed": SPLIT_IDS[split],
            "seeding": "each case: numpy SeedSequence([seed, split_seed, family index, case index + 1, 0]); "
                       "a family's split-level draws: case index 0",
            "cases_per_family": n,
            "y_axis": "truth coordinates have y pointing up in pictures; `window` is the part of "
                      "truth coordinates the whole canvas shows",
        },
        "cases": all_cases,
    }
    write_json(split_dir / "manifest.json", manifest)
    return manifest


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--split", choices=["tune", "test", "tune2", "tune3", "tune4", "all"], default="all",
                    help="all: tune and test; tune2, tune3, tune4: more tuning splits (more cases to choose on)")
    ap.add_argument("-o", "--output", type=Path, default=HERE / "inputs",
                    help="output folder (default: robustness/inputs)")
    ap.add_argument("--preview", action="store_true", help="also write preview_<family>.png contact sheets")
    ap.add_argument("--families", default=",".join(FAMILIES),
                    help="comma-separated subset of families (default: all)")
    ap.add_argument("--cases", type=int, default=CASES_PER_FAMILY,
                    help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    fams = [f for f in a.families.split(",") if f]
    unknown = [f for f in fams if f not in FAMILIES]
    if unknown:
        ap.error(f"unknown families {unknown}; known: {FAMILIES}")
    splits = ["tune", "test"] if a.split == "all" else [a.split]
    t0 = time.time()
    for s in splits:
        make_split(s, a.output, a.preview, fams, a.cases)
    print(f"wrote {', '.join(str(a.output / s) for s in splits)} in {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main()
