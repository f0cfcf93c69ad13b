# Shared by scripts/viewer_browser_test.sh and scripts/viewer_screenshot.sh (sourced, not
# run): Debian's headless Chromium found or installed, `ifslab serve` started on a free port,
# and shoot.py, which opens a page through the DevTools protocol, waits until every tile has
# arrived and takes a screenshot.
#
# The sourcing script sets $bin (the ifslab binary) and $tmp (a scratch folder), and calls
# viewer_find_browser, then start_server / stop_server; viewer_cleanup stops a server still
# running and removes $tmp (trap it on EXIT).

# Sets $browser: Chromium, installed from Debian's packages when absent; where it cannot be,
# exits 77 (skipped) saying why. Python 3 is needed as well (the protocol driver).
viewer_find_browser() {
  browser=$(command -v chromium || command -v chromium-browser || true)
  if [ -z "$browser" ]; then
    local sudo=""
    [ "$(id -u)" = 0 ] || sudo="sudo -n"
    if command -v apt-get >/dev/null 2>&1 \
      && { $sudo apt-get update -qq && $sudo apt-get install -y -qq chromium >/dev/null; }; then
      browser=$(command -v chromium)
    else
      echo "SKIPPED: Chromium is not installed and could not be installed (apt-get install chromium)"
      exit 77
    fi
  fi
  command -v python3 >/dev/null || { echo "SKIPPED: python3 is needed to drive the browser"; exit 77; }
  viewer_write_shooter "$tmp/shoot.py"
}

server=""
viewer_cleanup() {
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

# Writes shoot.py to $1:
#   python3 shoot.py BROWSER URL SIZE OUT.png PROFILE_DIR [WHEEL_STEPS]
# SIZE is the window's side (512) or WIDTHxHEIGHT (960x600). Chromium is driven through the
# DevTools protocol on a pipe (`--remote-debugging-pipe`, Python's standard library only, no
# driver, no websocket): it opens the page, waits until the page says every tile of its view
# has arrived (a plain `--screenshot` is taken at the page's load, before its tiles arrive),
# and takes the screenshot. With WHEEL_STEPS, the page is zoomed by the wheel as it loads and
# must have cancelled tiles (/stats.json).
viewer_write_shooter() {
  cat >"$1" <<'EOF'
import base64, json, os, subprocess, sys, time

browser, url, size, out, profile = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], sys.argv[5]
width, height = map(int, size.split("x")) if "x" in size else (int(size), int(size))
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
     "--no-first-run", f"--user-data-dir={profile}", f"--window-size={width},{height}",
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
         {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False}, session)
    start = time.time()
    call("Page.navigate", {"url": url}, session)
    if wheel:
        while call("Runtime.evaluate", {"expression": "document.readyState", "returnByValue": True},
                   session)["result"].get("value") != "complete":
            time.sleep(0.05)
        time.sleep(0.3)
        for _ in range(wheel):
            call("Input.dispatchMouseEvent", {"type": "mouseWheel", "x": width // 2, "y": height // 2,
                                               "deltaX": 0, "deltaY": -200}, session)
            time.sleep(0.15)
    ready = None
    while time.time() - start < 120:
        r = call("Runtime.evaluate", {"expression": "document.readyState == 'complete' && "
                                      "document.documentElement.dataset.ready",
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
}
