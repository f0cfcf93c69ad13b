#!/usr/bin/env bash
# The zoom viewer (`ifslab serve`) in a real browser: Debian's Chromium, headless, opens the
# page 2^20 deep on the Sierpiński triangle's left edge and takes a screenshot once every
# tile has arrived; the screenshot must be inked and agree with `ifslab render` of the same
# window (IoU of inked pixels, per pixel and per 4×4 block, the tiles' chaos game and the
# render's being different draws of the same measure). Then two more pages: a zoom by the
# wheel through slow tiles (1e8 points, one worker) that must cancel the tiles it passes
# (the page aborts them, the server stops or skips them: /stats.json), and a flame (the
# heart of paper_repro/fractal_flames) whose screenshot must match `ifslab flame render`
# of the same framing and samples.
#
#   scripts/viewer_browser_test.sh [IFSLAB_BINARY] [SCREENSHOT_OUT.png]
#
# The binary defaults to target/release/ifslab (built when missing). Chromium is installed
# from Debian's packages when absent; where it cannot be, the script exits 77 (skipped)
# saying why. Exit 0: passed; anything else: failed. The browser is driven through the
# DevTools protocol on a pipe (`--remote-debugging-pipe`, Python's standard library only):
# a plain `--screenshot` is taken at the page's load, before its tiles arrive.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/ifslab}
shot_out=${2:-}
if [ ! -x "$bin" ]; then
  cargo build --release -p ifslab-experiments --bin ifslab
  bin=target/release/ifslab
fi
tmp=$(mktemp -d)
# Chromium, the server and shoot.py (the DevTools driver): scripts/viewer_lib.sh.
# shellcheck source=scripts/viewer_lib.sh
source scripts/viewer_lib.sh
trap viewer_cleanup EXIT
viewer_find_browser

# Sierpiński with a square framing: the page's base window and `ifslab render`'s window.
cat >"$tmp/sierpinski.json" <<'EOF'
{
  "format": "ifslab-code/1",
  "name": "sierpinski",
  "dim": 2,
  "maps": [
    {"matrix": [[0.5, 0.0], [0.0, 0.5]], "offset": [0.0, 0.0]},
    {"matrix": [[0.5, 0.0], [0.0, 0.5]], "offset": [0.5, 0.0]},
    {"matrix": [[0.5, 0.0], [0.0, 0.5]], "offset": [0.25, 0.4330127018922193]}
  ],
  "framing": {"min": [-0.2, -0.2669872981077807], "max": [1.2, 1.1330127018922193]}
}
EOF
# A point of the left edge, (0, 0) + t (1/2, √3/2) with t = π/10.
cx=0.15707963267948966
cy=0.27206990463513267
side=512
zoom=1048576

start_server "$tmp/sierpinski.json"
page="${url}#level=20&x=${cx}&y=${cy}&bare=1&mode=coverage&cmap=white"
echo "page: $page"

python3 "$tmp/shoot.py" "$browser" "$page" "$side" "$tmp/page.png" "$tmp/profile" \
  || { echo "FAILED: the browser"; tail -n 20 "$tmp/profile.log"; exit 1; }
"$bin" render "$tmp/sierpinski.json" --size $side --zoom $zoom --center "$cx,$cy" \
  --points 20M -o "$tmp/render.png" 2>"$tmp/render.log" \
  || { echo "FAILED: ifslab render"; cat "$tmp/render.log"; exit 1; }
[ -n "$shot_out" ] && cp "$tmp/page.png" "$shot_out"

python3 - "$tmp/page.png" "$tmp/render.png" "$side" <<'EOF'
import struct, sys, zlib

def read_png(path):
    """8-bit grey, grey+alpha, RGB or RGBA, non-interlaced: a list of rows of ink (0/1)."""
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    pos, idat = 8, b""
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert depth == 8 and interlace == 0, (path, depth, interlace)
            channels = {0: 1, 2: 3, 4: 2, 6: 4}[colour]
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw, stride, prev, rows, i = zlib.decompress(idat), w * channels, None, [], 0
    for _ in range(h):
        f, line = raw[i], bytearray(raw[i + 1:i + 1 + stride])
        i += 1 + stride
        prev = prev or bytearray(stride)
        for x in range(stride):
            a = line[x - channels] if x >= channels else 0
            b, c = prev[x], prev[x - channels] if x >= channels else 0
            if f == 1: line[x] = (line[x] + a) & 255
            elif f == 2: line[x] = (line[x] + b) & 255
            elif f == 3: line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        prev = line
        colour_channels = min(channels, 3)
        rows.append([max(line[x * channels:x * channels + colour_channels]) > 127 for x in range(w)])
    return rows

page, ref, side = read_png(sys.argv[1]), read_png(sys.argv[2]), int(sys.argv[3])
assert len(page) == side and len(page[0]) == side, ("screenshot size", len(page), len(page[0]))
assert len(ref) == side and len(ref[0]) == side, "render size"

def iou(a, b):
    both = sum(x and y for ra, rb in zip(a, b) for x, y in zip(ra, rb))
    either = sum(x or y for ra, rb in zip(a, b) for x, y in zip(ra, rb))
    return both / max(either, 1)

def blocks(img, k=4):
    return [[any(img[y][x] for y in range(by, by + k) for x in range(bx, bx + k))
             for bx in range(0, side, k)] for by in range(0, side, k)]

inked_page = sum(map(sum, page)) / side**2
inked_ref = sum(map(sum, ref)) / side**2
px, bl = iou(page, ref), iou(blocks(page), blocks(ref))
print(f"inked: screenshot {inked_page:.3f}, render {inked_ref:.3f}; IoU per pixel {px:.3f}, per 4x4 block {bl:.3f}")
ok = inked_page > 0.02 and bl > 0.85 and px > 0.5
print("passed" if ok else "FAILED: the screenshot does not agree with the render")
sys.exit(0 if ok else 1)
EOF
stop_server

# Cancellation: slow tiles (1e8 points, about 1.6 s each on two cores, one worker), the
# page zoomed by the wheel 6 times as it loads: the tiles it passes are aborted by the page
# and stopped or skipped by the server.
start_server "$tmp/sierpinski.json" --points 1e8 --workers 1
python3 "$tmp/shoot.py" "$browser" "${url}#bare=1&mode=coverage" "$side" "$tmp/wheel.png" "$tmp/profile2" 6 \
  || { echo "FAILED: the browser (cancellation)"; tail -n 20 "$tmp/profile2.log"; exit 1; }
stop_server

# A flame: its tiles against `ifslab flame render` of the same framing. A 512² page at
# zoom 1 shows four level-1 tiles, each drawn with quality 4·8 on 256² (under 4M samples):
# the chaos game of quality 8 on 512², cut four ways.
heart=paper_repro/fractal_flames/results/fig4_heart/learned.flame
sed 's/quality="[0-9.]*"/quality="8"/' "$heart" >"$tmp/heart.flame"
start_server "$tmp/heart.flame"
python3 "$tmp/shoot.py" "$browser" "${url}#bare=1" "$side" "$tmp/flame_page.png" "$tmp/profile3" \
  || { echo "FAILED: the browser (flame)"; tail -n 20 "$tmp/profile3.log"; exit 1; }
stop_server
"$bin" flame render "$tmp/heart.flame" --size $side $side -o "$tmp/flame_render.png" 2>"$tmp/flame.log" \
  || { echo "FAILED: ifslab flame render"; cat "$tmp/flame.log"; exit 1; }
python3 - "$tmp/flame_page.png" "$tmp/flame_render.png" <<'EOF'
import struct, sys, zlib

def read_rgb(path):
    """8-bit RGB or RGBA, non-interlaced: a flat list of (r, g, b)."""
    data = open(path, "rb").read()
    pos, idat = 8, b""
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert depth == 8 and interlace == 0 and colour in (2, 6), (path, depth, colour)
            ch = 3 if colour == 2 else 4
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw, stride, prev, out, i = zlib.decompress(idat), w * ch, bytearray(w * ch), [], 0
    for _ in range(h):
        f, line = raw[i], bytearray(raw[i + 1:i + 1 + stride])
        i += 1 + stride
        for x in range(stride):
            a = line[x - ch] if x >= ch else 0
            b, c = prev[x], prev[x - ch] if x >= ch else 0
            if f == 1: line[x] = (line[x] + a) & 255
            elif f == 2: line[x] = (line[x] + b) & 255
            elif f == 3: line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        prev = line
        out += [tuple(line[x * ch:x * ch + 3]) for x in range(w)]
    return (w, h), out

(sa, page), (sb, ref) = read_rgb(sys.argv[1]), read_rgb(sys.argv[2])
assert sa == sb, (sa, sb)
close = sum(all(abs(p - q) <= 3 for p, q in zip(a, b)) for a, b in zip(page, ref)) / len(ref)
mean = sum(abs(p - q) for a, b in zip(page, ref) for p, q in zip(a, b)) / (3 * len(ref))
colours = len(set(ref))
print(f"flame: screenshot against ifslab flame render: {close:.4f} of pixels within 3 levels, "
      f"mean difference {mean:.3f} levels, {colours} colours")
ok = close > 0.99 and colours > 100
print("passed" if ok else "FAILED: the flame's screenshot does not agree with its render")
sys.exit(0 if ok else 1)
EOF
