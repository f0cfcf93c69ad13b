#!/usr/bin/env python3
"""Views of 3-D IFS codes drawn by a program independent of ifslab (NumPy only).

Its own chaos game, its own cameras (NeRF convention, written to a `transforms.json`
with `camera_angle_x`), its own rasteriser (points binned into a 4x supersampled grid,
a cell inked when a point falls in it, 4x4 cells averaged into grey coverage, dark ink
on white) and its own PNG writer (zlib), so `ifslab invert3d` is tried on pictures it
did not draw, through the NeRF camera path rather than a turntable.json.

    python scripts/render3d_views.py tetrahedron OUT/            # the Sierpinski tetrahedron
    python scripts/render3d_views.py fern OUT/                   # the README's 3-D fern
    python scripts/render3d_views.py random:3 OUT/               # a random 4-map code, seed 3
    python scripts/render3d_views.py code.json OUT/              # any ifslab-code/1, dim 3

OUT/ receives view_000.png ... and transforms.json, and truth.json, the code drawn (an
ifslab-code/1 file, "dim": 3), for `ifslab invert3d OUT --truth OUT/truth.json`.
The views are a turntable at --elevation degrees, starting --azimuth0 (10) degrees off the
+x axis (ifslab's turntables start on it), so only the poses can tell the reader where they
are. Views to score a fit on, which it never saw, come from another elevation and azimuth:

    python scripts/render3d_views.py random:3 OUT-other/ --views 4 --elevation 55 --azimuth0 32.5
"""

import argparse
import json
import struct
import sys
import zlib
from pathlib import Path

import numpy as np


def tetrahedron():
    verts = 0.8 * np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
    return [(0.5 * np.eye(3), 0.5 * v) for v in verts], None


def fern():
    """The classic fern of space conjugated by x -> 0.17 P x + (0, 0.45, -0.86), P
    swapping y and z (ifslab's model::map3::fern_3d, written out again here)."""
    classic = [
        ([[0, 0, 0], [0, 0.18, 0], [0, 0, 0]], [0, 0, 0]),
        ([[0.85, 0, 0], [0, 0.85, 0.1], [0, -0.1, 0.85]], [0, 1.6, 0]),
        ([[0.2, -0.2, 0], [0.2, 0.2, 0], [0, 0, 0.3]], [0, 0.8, 0]),
        ([[-0.2, 0.2, 0], [0.2, 0.2, 0], [0, 0, 0.3]], [0, 0.8, 0]),
    ]
    p = np.array([[1, 0, 0], [0, 0, 1], [0, 1, 0]], float)
    a, c = 0.17 * p, np.array([0, 0.45, -0.86])
    a_inv = np.linalg.inv(a)
    maps = []
    for m, b in classic:
        m, b = np.array(m, float), np.array(b, float)
        # y = a (m (a^-1 (x - c)) + b) + c
        mm = a @ m @ a_inv
        maps.append((mm, a @ b + c - mm @ c))
    return maps, [0.01, 0.85, 0.07, 0.07]


def random_code(seed, k=4):
    """k maps: a random rotation, singular values in [0.3, 0.6], a random mirror, a
    random rotation, offsets in [-0.5, 0.5]^3; then conjugated by a homothety so that
    the attractor's box is centred and its longest side is 1.6."""
    rng = np.random.default_rng(seed)

    def rotation():
        q, r = np.linalg.qr(rng.normal(size=(3, 3)))
        q = q * np.sign(np.diag(r))
        if np.linalg.det(q) < 0:
            q[:, 0] = -q[:, 0]
        return q

    maps = []
    for _ in range(k):
        s = rng.uniform(0.3, 0.6, 3)
        if rng.random() < 0.5:
            s[2] = -s[2]
        maps.append((rotation() @ np.diag(s) @ rotation().T, rng.uniform(-0.5, 0.5, 3)))
    pts = chaos_game(maps, None, 20000, 1)
    lo, hi = pts.min(0), pts.max(0)
    a = 1.6 / (hi - lo).max()
    c = -a * 0.5 * (lo + hi)
    # y = a x + c: maps become m and a b + c - m c.
    return [(m, a * b + c - m @ c) for m, b in maps], None


def load_code(path):
    code = json.loads(Path(path).read_text())
    if code.get("dim") != 3:
        sys.exit(f"{path}: not a 3-D code (\"dim\": 3)")
    maps = [(np.array(m["matrix"], float), np.array(m["offset"], float)) for m in code["maps"]]
    return maps, code.get("probabilities")


def chaos_game(maps, probs, n, seed, steps=60, warmup=20):
    """n trajectories of `steps` steps from uniform points in [-1, 1]^3, the first
    `warmup` dropped; maps drawn with `probs` (uniform when None)."""
    rng = np.random.default_rng(seed)
    ms = np.stack([m for m, _ in maps])
    bs = np.stack([b for _, b in maps])
    p = np.full(len(maps), 1 / len(maps)) if probs is None else np.array(probs, float)
    x = rng.uniform(-1, 1, (n, 3))
    out = []
    for t in range(steps):
        k = rng.choice(len(maps), size=n, p=p / p.sum())
        x = np.einsum("nij,nj->ni", ms[k], x) + bs[k]
        if t >= warmup:
            out.append(x.copy())
    return np.concatenate(out)


def look_at(eye, up=(0.0, 0.0, 1.0)):
    """Camera-to-world 4x4 (NeRF/OpenGL: columns right, up, back, position)."""
    eye = np.asarray(eye, float)
    back = eye / np.linalg.norm(eye)
    right = np.cross(up, back)
    right /= np.linalg.norm(right)
    upv = np.cross(back, right)
    c2w = np.eye(4)
    c2w[:3, 0], c2w[:3, 1], c2w[:3, 2], c2w[:3, 3] = right, upv, back, eye
    return c2w


def draw(points, c2w, fov_x, size, ss=4):
    """Grey coverage (ink 1) of the points seen by a pinhole: a cell of the ss-times
    supersampled grid is inked when a point falls in it; ss x ss cells averaged."""
    rot, eye = c2w[:3, :3], c2w[:3, 3]
    pc = (points - eye) @ rot  # world -> camera: R^T (p - eye), row vectors
    z = -pc[:, 2]
    keep = z > 1e-3
    f = 0.5 * size / np.tan(0.5 * fov_x)
    u = 0.5 * size + f * pc[keep, 0] / z[keep]
    v = 0.5 * size - f * pc[keep, 1] / z[keep]
    i, j = np.floor(u * ss).astype(int), np.floor(v * ss).astype(int)
    inside = (i >= 0) & (j >= 0) & (i < size * ss) & (j < size * ss)
    grid = np.zeros((size * ss, size * ss), bool)
    grid[j[inside], i[inside]] = True
    return grid.reshape(size, ss, size, ss).mean(axis=(1, 3))


def write_png(path, grey):
    """8-bit grey PNG of values in [0, 1]."""
    h, w = grey.shape
    rows = (np.clip(grey, 0, 1) * 255 + 0.5).astype(np.uint8)
    raw = b"".join(b"\x00" + rows[r].tobytes() for r in range(h))

    def chunk(kind, data):
        c = struct.pack(">I", len(data)) + kind + data
        return c + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    Path(path).write_bytes(png)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("code", help="tetrahedron | fern | random:SEED | a 3-D code file")
    ap.add_argument("out", type=Path)
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--elevation", type=float, default=25.0)
    ap.add_argument(
        "--azimuth0", type=float, default=10.0,
        help="azimuth of the first view, degrees (other angles draw views to score on)",
    )
    ap.add_argument("--distance", type=float, default=4.0)
    ap.add_argument("--fov", type=float, default=50.0, help="horizontal field of view, degrees")
    ap.add_argument("--points", type=int, default=20000, help="trajectories (40 points each)")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()

    if a.code == "tetrahedron":
        maps, probs = tetrahedron()
    elif a.code == "fern":
        maps, probs = fern()
    elif a.code.startswith("random:"):
        maps, probs = random_code(int(a.code.split(":", 1)[1]))
    else:
        maps, probs = load_code(a.code)
    points = chaos_game(maps, probs, a.points, a.seed + 1)
    a.out.mkdir(parents=True, exist_ok=True)
    fov = np.radians(a.fov)
    e = np.radians(a.elevation)
    frames = []
    for k in range(a.views):
        az = np.radians(a.azimuth0) + 2 * np.pi * k / a.views
        eye = a.distance * np.array([np.cos(e) * np.cos(az), np.cos(e) * np.sin(az), np.sin(e)])
        c2w = look_at(eye)
        name = f"view_{k:03d}"
        write_png(a.out / f"{name}.png", 1.0 - draw(points, c2w, fov, a.size))
        frames.append({"file_path": name, "transform_matrix": c2w.tolist()})
    (a.out / "transforms.json").write_text(
        json.dumps({"camera_angle_x": float(fov), "frames": frames}, indent=1)
    )
    truth = {
        "format": "ifslab-code/1",
        "name": a.code,
        "dim": 3,
        "maps": [{"matrix": m.tolist(), "offset": b.tolist()} for m, b in maps],
    }
    if probs is not None:
        truth["probabilities"] = list(probs)
    (a.out / "truth.json").write_text(json.dumps(truth, indent=1))
    print(f"{a.views} views of {a.size}^2 of {a.code} -> {a.out}")


if __name__ == "__main__":
    main()
