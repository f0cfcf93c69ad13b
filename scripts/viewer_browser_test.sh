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
browser=$(command -v chromium || command -v chromium-browser || true)
if [ -z "$browser" ]; then
  sudo=""
  [ "$(id -u)" = 0 ] || sudo="sudo -n"
  if command -v apt-get >/dev/null 2>&1 \
    && { $sudo apt-get update -qq && $sudo apt-get install -y -qq chromium >/dev/null; }; then
    browser=$(command -v chromium)
  else
    echo "SKIPPED: Chromium is not installed and could not be installed (apt-get install chromium)"
    exit 77
  fi
fi
command -v python3 >/dev/null || { echo "SKIPPED: python3 is needed to compare the images"; exit 77; }

tmp=$(mktemp -d)
server=""
cleanup() {
  [ -n "$server" ] && kill "$server" 2>/dev/null || true
  rm -rf "$tmp"
}
# Starts `ifslab serve ARGS…` on a free port; sets $server and $url.
start_server() {
  "$bin" serve "$@" --port 0 2>"$tmp/serve.log" &
  server=$!
  url=""
  for _ in $(seq 1 100); do
    url=$(grep -o 'http://127.0.0.1:[0-9]*/' "$tmp/serve.log" | head -n 1 || true)
    [ -n "$url" ] && break
    sleep 0.1
  done
  [ -n "$url" ] || { echo "FAILED: the server did not start"; cat "$tmp/serve.log"; exit 1; }
}
stop_server() {
  kill "$server" 2>/dev/null || true
  wait "$server" 2>/dev/null || true
  server=""
}
trap cleanup EXIT

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

# Chromium driven through the DevTools protocol on a pipe (no driver, no websocket): open the
# page, wait until it says every tile of its view has arrived, take the screenshot.
cat >"$tmp/shoot.py" <<'EOF'
import base64, json, os, subprocess, sys, time

browser, url, side, out, profile = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4], sys.argv[5]
# Wheel steps (each 2^0.5 deeper about the centre) sent as the page loads, 150 ms apart.
wheel = int(sys.argv[6]) if len(sys.argv) > 6 else 0
to_chrome_r, to_chrome_w = os.pipe()
from_chrome_r, from_chrome_w = os.pipe()
# The protocol's pipe is the child's fds 3 (commands) and 4 (replies).
def child():
    r, w = os.dup(to_chrome_r), os.dup(from_chrome_w)  # off 3 and 4 before taking them
    r, w = os.dup2(r, 100), os.dup2(w, 101)
    os.dup2(r, 3)
    os.dup2(w, 4)
proc = subprocess.Popen(
    [browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--mute-audio",
     "--no-first-run", f"--user-data-dir={profile}", f"--window-size={side},{side}",
     "--remote-debugging-pipe", "about:blank"],
    preexec_fn=child, pass_fds=(3, 4), stdout=subprocess.DEVNULL, stderr=open(profile + ".log", "w"))
os.close(to_chrome_r)
os.close(from_chrome_w)
out_pipe, in_pipe, buf, ids = os.fdopen(to_chrome_w, "wb"), os.fdopen(from_chrome_r, "rb"), b"", [0]

def call(method, params=None, session=None, timeout=60):
    global buf
    ids[0] += 1
    msg = {"id": ids[0], "method": method, "params": params or {}}
    if session:
        msg["sessionId"] = session
    out_pipe.write(json.dumps(msg).encode() + b"\0")
    out_pipe.flush()
    deadline = time.time() + timeout
    while time.time() < deadline:
        while b"\0" in buf:
            raw, buf = buf.split(b"\0", 1)
            reply = json.loads(raw)
            if reply.get("id") == ids[0]:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply["result"]
        chunk = os.read(in_pipe.fileno(), 1 << 20)
        if not chunk:
            raise RuntimeError("chromium closed the pipe")
        buf += chunk
    raise RuntimeError(f"{method}: no reply in {timeout} s")

try:
    target = call("Target.createTarget", {"url": "about:blank"})["targetId"]
    session = call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
    call("Emulation.setDeviceMetricsOverride",
         {"width": side, "height": side, "deviceScaleFactor": 1, "mobile": False}, session)
    start = time.time()
    call("Page.navigate", {"url": url}, session)
    if wheel:
        while call("Runtime.evaluate", {"expression": "document.readyState", "returnByValue": True},
                   session)["result"].get("value") != "complete":
            time.sleep(0.05)
        time.sleep(0.3)
        for _ in range(wheel):
            call("Input.dispatchMouseEvent", {"type": "mouseWheel", "x": side // 2, "y": side // 2,
                                               "deltaX": 0, "deltaY": -200}, session)
            time.sleep(0.15)
    ready = None
    while time.time() - start < 120:
        r = call("Runtime.evaluate", {"expression": "document.documentElement.dataset.ready",
                                      "returnByValue": True}, session)
        ready = r["result"].get("value")
        if ready == "true":
            break
        time.sleep(0.2)
    if ready != "true":
        sys.exit(f"FAILED: the page's tiles did not all arrive in 120 s (ready = {ready})")
    if wheel:
        r = call("Runtime.evaluate", {"expression": "fetch('/stats.json').then(r => r.text()).then(t => "
                 "JSON.stringify([document.documentElement.dataset.cancelled, JSON.parse(t)]))",
                 "awaitPromise": True, "returnByValue": True}, session)
        aborted, stats = json.loads(r["result"]["value"])
        print(f"wheel x{wheel}: the page aborted {aborted} tile requests; server: {stats}")
        stopped = stats["cancelled_queued"] + stats["cancelled_drawing"] + stats["stale"]
        if int(aborted) == 0 or stopped == 0:
            sys.exit("FAILED: zooming through slow tiles cancelled none")
    shot = call("Page.captureScreenshot", {"format": "png"}, session)
    open(out, "wb").write(base64.b64decode(shot["data"]))
    print(f"page ready and captured in {time.time() - start:.2f} s")
finally:
    try:
        call("Browser.close", timeout=10)
    except Exception:
        pass
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
EOF
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
