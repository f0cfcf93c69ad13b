// ifslab serve's viewer (MIT OR Apache-2.0, see /LICENSE). Hand-written, no dependencies.
//
// Every view shows the same window of the plane: the server's square base window zoomed
// 2^z around (cx, cy), z = 0 fitting the base window to a view's shorter side. Drag pans,
// the wheel zooms about the pointer, a double click zooms in 2x. Code views are drawn from
// tiles at power-of-two levels (the level whose tile pixels are closest to the screen's),
// with already-loaded coarser tiles standing in until they arrive; picture views (a run's
// target) are the picture laid over the base window, one square per pixel.
//
// The initial view comes from the URL's fragment: #level=Z&x=CX&y=CY&mode=M&cmap=C, and
// bare=1 for one view alone filling the window (view=NAME picks which). Tiles the view no
// longer shows are cancelled: their requests are aborted at the next frame (the browser
// closes their connections, and the server stops drawing them). Each view change also
// starts a new generation; tiles are asked for with it and the page's id, and the server
// skips or stops those of older generations (answering 409, after which the tile is asked
// for again if it is still shown). A flame's tiles come in its own colours (mode colour).
(function () {
  "use strict";
  const info = window.IFSLAB;
  const T = info.tile_size;
  const B = info.base;
  const S = B.max[0] - B.min[0];
  const HOME = [(B.min[0] + B.max[0]) / 2, (B.min[1] + B.max[1]) / 2];
  const MAX_Z = info.max_level + 4; // past the deepest tiles, the last ones enlarged
  const MIN_Z = -4;
  const CACHE = 800; // tiles kept decoded
  const sid = String(Math.floor(Math.random() * 9007199254740991));
  let gen = 0;

  const view = { z: 0, cx: HOME[0], cy: HOME[1], mode: "coverage", cmap: "inferno" };
  const hash = new URLSearchParams(location.hash.slice(1));
  const num = (k) => {
    const v = Number(hash.get(k));
    return hash.has(k) && Number.isFinite(v) ? v : null;
  };
  if (num("level") !== null) view.z = Math.min(MAX_Z, Math.max(MIN_Z, num("level")));
  if (num("x") !== null) view.cx = num("x");
  if (num("y") !== null) view.cy = num("y");
  if (info.modes.includes(hash.get("mode"))) view.mode = hash.get("mode");
  if (info.cmaps.includes(hash.get("cmap"))) view.cmap = hash.get("cmap");
  if (!info.modes.includes(view.mode)) view.mode = info.modes[0];
  if (!info.cmaps.length) view.cmap = "";
  const bare = hash.get("bare") === "1";

  const tiles = new Map(); // key -> ImageBitmap, oldest first
  const inflight = new Map(); // keys asked for, not answered yet -> their AbortController
  let wanted = new Set(); // keys the last frame still needed
  const failed = new Set();
  const $ = (id) => document.getElementById(id);

  document.title = "ifslab · " + info.title;
  $("title").textContent = info.title;
  if (info.note) {
    $("note").textContent = info.note;
    $("note").title = info.note;
  }
  for (const [id, list, value] of [["mode", info.modes, view.mode], ["cmap", info.cmaps, view.cmap]]) {
    const sel = $(id);
    if (list.length < 2) sel.parentElement.hidden = true;
    for (const name of list) sel.add(new Option(name, name, false, name === value));
    sel.addEventListener("change", () => {
      view[id] = sel.value;
      failed.clear();
      changed();
    });
  }
  $("reset").addEventListener("click", () => {
    Object.assign(view, { z: 0, cx: HOME[0], cy: HOME[1] });
    changed();
  });
  if (bare) document.body.classList.add("bare");
  if (info.loss && !bare) {
    $("loss").hidden = false;
    $("loss-img").src = info.loss;
    $("views").classList.add("with-loss");
  }

  let shown = info.views;
  if (bare) {
    const named = info.views.filter((v) => v.name === hash.get("view"));
    shown = named.length ? named : info.views.filter((v) => v.kind === "tiles").slice(0, 1);
  }
  const panels = shown.map((def) => {
    const el = document.createElement("div");
    el.className = "view";
    const canvas = document.createElement("canvas");
    const label = document.createElement("div");
    label.className = "label";
    label.textContent = def.name;
    el.append(canvas, label);
    $("views").append(el);
    const panel = { def, canvas, ctx: canvas.getContext("2d"), picture: null };
    if (def.kind === "picture") {
      const img = new Image();
      img.onload = () => {
        panel.picture = img;
        schedule();
      };
      img.src = def.url;
    }
    listen(panel);
    return panel;
  });

  // CSS pixels per world unit in a panel.
  function scale(panel) {
    const r = panel.canvas.getBoundingClientRect();
    return (Math.min(r.width, r.height) * Math.pow(2, view.z)) / S;
  }

  function listen(panel) {
    const c = panel.canvas;
    let drag = null;
    c.addEventListener("pointerdown", (e) => {
      drag = { x: e.clientX, y: e.clientY, cx: view.cx, cy: view.cy, k: scale(panel) };
      c.setPointerCapture(e.pointerId);
      c.classList.add("dragging");
    });
    c.addEventListener("pointermove", (e) => {
      if (!drag) return;
      view.cx = drag.cx - (e.clientX - drag.x) / drag.k;
      view.cy = drag.cy + (e.clientY - drag.y) / drag.k;
      changed();
    });
    const end = () => {
      drag = null;
      c.classList.remove("dragging");
    };
    c.addEventListener("pointerup", end);
    c.addEventListener("pointercancel", end);
    c.addEventListener("wheel", (e) => {
      e.preventDefault();
      const unit = e.deltaMode === 1 ? 40 : e.deltaMode === 2 ? 800 : 1;
      zoomAt(panel, e, Math.max(-1, Math.min(1, (-e.deltaY * unit) / 400)));
    }, { passive: false });
    c.addEventListener("dblclick", (e) => zoomAt(panel, e, e.shiftKey ? -1 : 1));
  }

  // Zooms by 2^dz keeping the world point under the pointer where it is.
  function zoomAt(panel, e, dz) {
    const r = panel.canvas.getBoundingClientRect();
    const mx = e.clientX - r.left - r.width / 2;
    const my = e.clientY - r.top - r.height / 2;
    const k0 = scale(panel);
    const wx = view.cx + mx / k0;
    const wy = view.cy - my / k0;
    view.z = Math.min(MAX_Z, Math.max(MIN_Z, view.z + dz));
    const k1 = scale(panel);
    view.cx = wx - mx / k1;
    view.cy = wy + my / k1;
    changed();
  }

  let hashTimer = 0;
  function changed() {
    gen += 1;
    schedule();
    clearTimeout(hashTimer);
    hashTimer = setTimeout(() => {
      const h = new URLSearchParams({
        level: String(view.z), x: String(view.cx), y: String(view.cy), mode: view.mode,
      });
      if (view.cmap) h.set("cmap", view.cmap);
      if (bare) h.set("bare", "1");
      history.replaceState(null, "", "#" + h.toString());
    }, 200);
  }

  let pending = false;
  function schedule() {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => {
      pending = false;
      draw();
    });
  }
  window.addEventListener("resize", schedule);

  function message(text) {
    $("message").textContent = text;
  }

  // Asks for a tile; a tile the view stops showing is aborted (see cancelStale).
  function fetchTile(key, url) {
    const ctl = new AbortController();
    inflight.set(key, ctl);
    fetch(url, { signal: ctl.signal })
      .then(async (r) => {
        if (r.ok) {
          const bmp = await createImageBitmap(await r.blob());
          tiles.set(key, bmp);
          while (tiles.size > CACHE) tiles.delete(tiles.keys().next().value);
        } else if (r.status !== 409) {
          failed.add(key);
          message(`tile ${key}: ${r.status} ${(await r.text()).trim()}`);
        }
      })
      .catch((e) => {
        if (e.name !== "AbortError") {
          failed.add(key);
          message(`tile ${key}: ${e}`);
        }
      })
      .finally(() => {
        if (inflight.get(key) === ctl) inflight.delete(key);
        schedule();
      });
  }

  // Aborts the requests of tiles the last frame did not need.
  function cancelStale() {
    for (const [key, ctl] of inflight) {
      if (!wanted.has(key)) {
        inflight.delete(key);
        ctl.abort();
        cancelled += 1;
      }
    }
  }
  let cancelled = 0;

  function draw() {
    wanted = new Set();
    let waiting = 0;
    let level = 0;
    for (const p of panels) {
      const dpr = window.devicePixelRatio || 1;
      const r = p.canvas.getBoundingClientRect();
      const [w, h] = [Math.round(r.width * dpr), Math.round(r.height * dpr)];
      if (p.canvas.width !== w || p.canvas.height !== h) {
        p.canvas.width = w;
        p.canvas.height = h;
      }
      const ctx = p.ctx;
      ctx.setTransform(1, 0, 0, 1, 0, 0);
      ctx.fillStyle = "#000";
      ctx.fillRect(0, 0, w, h);
      ctx.imageSmoothingEnabled = false;
      // Device pixels per world unit, and the visible world rectangle.
      const k = (scale(p) * dpr);
      const vis = { x0: view.cx - w / 2 / k, x1: view.cx + w / 2 / k, y0: view.cy - h / 2 / k, y1: view.cy + h / 2 / k };
      const sx = (x) => (x - view.cx) * k + w / 2;
      const sy = (y) => (view.cy - y) * k + h / 2;
      if (p.def.kind === "picture") {
        if (!p.picture) {
          waiting += 1;
          continue;
        }
        drawPicture(ctx, p.picture, vis, sx, sy);
      } else {
        const want = Math.round(view.z + Math.log2((Math.min(w, h) / T)));
        level = Math.max(0, Math.min(info.max_level, want));
        waiting += drawTiles(ctx, p.def, level, vis, sx, sy);
      }
    }
    // As many digits as the zoom makes significant.
    const digits = Math.min(17, Math.max(5, Math.ceil(view.z * Math.LOG10E * Math.LN2) + 4));
    $("where").textContent =
      `zoom 2^${view.z.toFixed(2)} at (${view.cx.toPrecision(digits)}, ${view.cy.toPrecision(digits)}), tiles of level ${level}`;
    cancelStale();
    // For tests and scripts: every tile of the view is drawn; tile requests aborted so far.
    document.documentElement.dataset.ready = waiting === 0 && inflight.size === 0 ? "true" : "false";
    document.documentElement.dataset.cancelled = String(cancelled);
  }

  // The picture's pixels under the view, each as a square of the base window.
  function drawPicture(ctx, img, vis, sx, sy) {
    const [iw, ih] = [img.naturalWidth, img.naturalHeight];
    const px = (x) => ((x - B.min[0]) / S) * iw;
    const py = (y) => ((B.max[1] - y) / S) * ih;
    const i0 = Math.max(0, Math.floor(px(vis.x0)));
    const i1 = Math.min(iw, Math.ceil(px(vis.x1)));
    const j0 = Math.max(0, Math.floor(py(vis.y1)));
    const j1 = Math.min(ih, Math.ceil(py(vis.y0)));
    if (i1 <= i0 || j1 <= j0) return;
    const left = sx(B.min[0] + (i0 / iw) * S);
    const right = sx(B.min[0] + (i1 / iw) * S);
    const top = sy(B.max[1] - (j0 / ih) * S);
    const bottom = sy(B.max[1] - (j1 / ih) * S);
    ctx.drawImage(img, i0, j0, i1 - i0, j1 - j0, left, top, right - left, bottom - top);
  }

  // The tiles of `level` under the view (coarser loaded tiles in place of missing ones);
  // returns how many are still missing.
  function drawTiles(ctx, def, level, vis, sx, sy) {
    const n = Math.pow(2, level);
    const ts = S / n;
    const clamp = (v) => Math.max(0, Math.min(n - 1, v));
    const i0 = clamp(Math.floor((vis.x0 - B.min[0]) / ts));
    const i1 = clamp(Math.floor((vis.x1 - B.min[0]) / ts));
    const j0 = clamp(Math.floor((B.max[1] - vis.y1) / ts));
    const j1 = clamp(Math.floor((B.max[1] - vis.y0) / ts));
    if ((vis.x1 < B.min[0]) || (vis.x0 > B.max[0]) || (vis.y1 < B.min[1]) || (vis.y0 > B.max[1])) return 0;
    const key = (l, i, j) => `${def.name}/${view.mode}/${view.cmap}/${l}/${i}/${j}`;
    const mode = def.modes.includes(view.mode) ? view.mode : def.modes[0];
    let missing = 0;
    for (let j = j0; j <= j1; j++) {
      for (let i = i0; i <= i1; i++) {
        const left = Math.floor(sx(B.min[0] + i * ts));
        const top = Math.floor(sy(B.max[1] - j * ts));
        const right = Math.ceil(sx(B.min[0] + (i + 1) * ts));
        const bottom = Math.ceil(sy(B.max[1] - (j + 1) * ts));
        const k = key(level, i, j);
        const bmp = tiles.get(k);
        if (bmp) {
          tiles.delete(k); // most recently used last
          tiles.set(k, bmp);
          ctx.drawImage(bmp, left, top, right - left, bottom - top);
          continue;
        }
        if (failed.has(k)) continue;
        missing += 1;
        wanted.add(k);
        if (!inflight.has(k)) {
          const q = new URLSearchParams({ level: String(level), x: String(i), y: String(j), mode });
          if (view.cmap) q.set("cmap", view.cmap);
          q.set("gen", String(gen));
          q.set("sid", sid);
          fetchTile(k, `${def.url}?${q}`);
        }
        for (let d = 1; d <= 8 && d <= level; d++) {
          const f = Math.pow(2, d);
          const [pi, pj] = [Math.floor(i / f), Math.floor(j / f)];
          const up = tiles.get(key(level - d, pi, pj));
          if (up) {
            const sub = T / f;
            ctx.drawImage(up, (i - pi * f) * sub, (j - pj * f) * sub, sub, sub, left, top, right - left, bottom - top);
            break;
          }
        }
      }
    }
    return missing;
  }

  schedule();
})();
