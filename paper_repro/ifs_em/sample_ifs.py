#!/usr/bin/env python3
"""Point clouds of IFS attractors made without ifslab (Python standard library only).

The EM reproduction and the convergence tests read data that ifslab's own chaos game did not
make: this script writes CSV files of points on attractors of similitude IFSs, in any frame,
with its own generator (Python's Mersenne Twister), one long chaos-game trajectory after a
burn-in, and a header line, as a user's own tool might.

    python3 sample_ifs.py triangle -n 10000 --seed 1 -o pts.csv
    python3 sample_ifs.py triangle -n 10000 --scale 1000 --rotate 30 --shift 5e3,-2e3 -o big.csv
    python3 sample_ifs.py random --maps 4 --code-seed 7 -n 10000 -o r.csv --code-out r.json

Shapes (all similitudes with proper rotations, so inside EM's model class):

  triangle     Sierpinski triangle on (0,0), (1,0), (0.5,1): three maps x -> (x + v)/2
  equilateral  Sierpinski triangle on (0,0), (1,0), (0.5, sqrt(3)/2)
  pinwheel4    four maps of ratio 0.45 rotated by 20 degrees towards a square's corners
  spiral5      five maps: a ratio-0.4 pentagon of maps, each rotated by 36 degrees
  carpet8      Sierpinski carpet: eight maps of ratio 1/3 (a solid-looking K = 8 code)
  square4      a filled square: four maps x -> (x + v)/2 towards its corners (a solid
               attractor: every point of the square, the pieces only touching)
  random       --maps similitudes with random ratios in [0.3, 0.5], rotations and fixed
               points (--code-seed), redrawn until the pieces' fixed-point spread is usable

Probabilities are proportional to s^d with d the similarity dimension (the natural measure);
--uniform gives every map the same probability.

The frame options act on the finished points in this order: rotate (degrees, about the
origin), scale, shift. The code in that frame (the conjugated maps) goes to --code-out as an
ifslab code file (`ifslab fit-points ... --truth CODE.json` compares fits with it).
"""

import argparse
import json
import math
import random
import sys


def similitude(s, deg, fixed):
    """Map x -> s R(deg) (x - p) + p, as (s, angle in radians, translation)."""
    a = math.radians(deg)
    c, d = math.cos(a), math.sin(a)
    px, py = fixed
    tx = px - s * (c * px - d * py)
    ty = py - s * (d * px + c * py)
    return (s, a, (tx, ty))


def shape_maps(name, k, code_seed):
    if name == "triangle":
        return [similitude(0.5, 0.0, v) for v in [(0.0, 0.0), (1.0, 0.0), (0.5, 1.0)]]
    if name == "equilateral":
        h = math.sqrt(3.0) / 2.0
        return [similitude(0.5, 0.0, v) for v in [(0.0, 0.0), (1.0, 0.0), (0.5, h)]]
    if name == "pinwheel4":
        return [similitude(0.45, 20.0, v) for v in [(0, 0), (1, 0), (1, 1), (0, 1)]]
    if name == "spiral5":
        pts = [(math.cos(2 * math.pi * i / 5), math.sin(2 * math.pi * i / 5)) for i in range(5)]
        return [similitude(0.4, 36.0, p) for p in pts]
    if name == "square4":
        return [similitude(0.5, 0.0, v) for v in [(0, 0), (1, 0), (1, 1), (0, 1)]]
    if name == "carpet8":
        pts = [(i, j) for i in range(3) for j in range(3) if (i, j) != (1, 1)]
        return [similitude(1.0 / 3.0, 0.0, (i / 2.0, j / 2.0)) for i, j in pts]
    if name == "random":
        rng = random.Random(code_seed)
        while True:
            maps = []
            for _ in range(k):
                s = rng.uniform(0.3, 0.5)
                deg = rng.uniform(-180.0, 180.0)
                r = math.sqrt(rng.random())
                phi = rng.uniform(0.0, 2.0 * math.pi)
                maps.append(similitude(s, deg, (r * math.cos(phi), r * math.sin(phi))))
            # Fixed points too close together make pieces that overlap almost entirely,
            # which no method can tell apart; keep codes whose fixed points are spread out.
            fps = [fixed_point(m) for m in maps]
            gap = min(
                math.dist(fps[i], fps[j]) for i in range(k) for j in range(i + 1, k)
            )
            if gap > 0.5:
                return maps
    raise SystemExit(f"unknown shape {name!r}")


def fixed_point(m):
    s, a, (tx, ty) = m
    # Solve x = s R x + t: (I - sR) x = t.
    c, d = s * math.cos(a), s * math.sin(a)
    m00, m01, m10, m11 = 1 - c, d, -d, 1 - c
    det = m00 * m11 - m01 * m10
    return ((m11 * tx - m01 * ty) / det, (-m10 * tx + m00 * ty) / det)


def apply(m, x, y):
    s, a, (tx, ty) = m
    c, d = math.cos(a), math.sin(a)
    return (s * (c * x - d * y) + tx, s * (d * x + c * y) + ty)


def similarity_dimension(scales):
    """The d with sum s_k^d = 1 (bisection)."""
    lo, hi = 0.0, 10.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if sum(s**mid for s in scales) > 1.0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shape")
    ap.add_argument("-n", "--points", type=int, default=10000)
    ap.add_argument("--seed", type=int, default=0, help="chaos-game seed")
    ap.add_argument("--maps", type=int, default=3, help="maps of a random code")
    ap.add_argument("--code-seed", type=int, default=0, help="seed of a random code")
    ap.add_argument("--uniform", action="store_true", help="equal map probabilities")
    ap.add_argument("--rotate", type=float, default=0.0, help="degrees")
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--shift", default="0,0", help="dx,dy")
    ap.add_argument("--burn-in", type=int, default=1000)
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--code-out", help="write the code in the output frame (ifslab code file)")
    a = ap.parse_args()
    if a.points < 1:
        raise SystemExit("--points must be at least 1")
    maps = shape_maps(a.shape, a.maps, a.code_seed)
    scales = [m[0] for m in maps]
    if a.uniform:
        probs = [1.0 / len(maps)] * len(maps)
    else:
        d = similarity_dimension(scales)
        probs = [s**d for s in scales]
        total = sum(probs)
        probs = [p / total for p in probs]
    cum = []
    acc = 0.0
    for p in probs:
        acc += p
        cum.append(acc)
    rng = random.Random(a.seed)
    th = math.radians(a.rotate)
    rc, rs = math.cos(th), math.sin(th)
    dx, dy = (float(v) for v in a.shift.split(","))

    def frame(x, y):
        return (a.scale * (rc * x - rs * y) + dx, a.scale * (rs * x + rc * y) + dy)

    x, y = rng.random(), rng.random()
    out = ["x,y"]
    for i in range(a.burn_in + a.points):
        u = rng.random() * cum[-1]
        k = next(j for j, c in enumerate(cum) if u < c)
        x, y = apply(maps[k], x, y)
        if i >= a.burn_in:
            fx, fy = frame(x, y)
            out.append(f"{fx:.10g},{fy:.10g}")
    with open(a.output, "w") as f:
        f.write("\n".join(out) + "\n")
    if a.code_out:
        # In the frame F(x) = scale R x + shift a map becomes F S F^-1: the same ratio and
        # angle (plane rotations commute), with fixed point F(p); written as an ifslab code.
        out_maps = []
        for m in maps:
            s, ang, _ = m
            px, py = frame(*fixed_point(m))
            c, d = s * math.cos(ang), s * math.sin(ang)
            out_maps.append({
                "matrix": [[c, -d], [d, c]],
                "offset": [px - (c * px - d * py), py - (d * px + c * py)],
            })
        code = {
            "format": "ifslab-code/1",
            "name": a.shape,
            "dim": 2,
            "maps": out_maps,
            "probabilities": probs,
            "meta": {"about": "written by paper_repro/ifs_em/sample_ifs.py",
                     "scales": scales, "angles_deg": [math.degrees(m[1]) for m in maps]},
        }
        with open(a.code_out, "w") as f:
            json.dump(code, f, indent=1)
    print(f"{a.output}: {a.points} points of {a.shape} ({len(maps)} maps)", file=sys.stderr)


if __name__ == "__main__":
    main()
