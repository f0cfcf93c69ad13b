//! `ifslab serve`'s HTTP endpoints, through a server started in-process on a free port and
//! a plain TCP client: tiles at the top level and 2²⁰ deep, refusals, empty tiles, stale
//! generations, the run folder's page, tiles cancelled when their client leaves, kept-alive
//! connections that never wait for one another, a flame's tiles.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use ifslab::model::IfsCode;
use ifslab::model::affine::Affine2;
use ifslab::model::code::Window;
use ifslab_experiments::serve::{RunningServer, ServeOptions, Site, TileOptions, TileStats, serve};

/// A response: status, headers (lower-case names), body.
struct Reply {
    status: u16,
    headers: Vec<(String, String)>,
    body: Vec<u8>,
}

impl Reply {
    fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }
}

/// `GET path` over a fresh connection (HTTP/1.1, `Connection: close`).
fn get(addr: SocketAddr, path: &str) -> Reply {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(120))).unwrap();
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).unwrap();
    let end = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a header block");
    parse_reply(&raw, end, path)
}

/// `GET path` on a kept-alive connection: the answer read to its `Content-Length`, the
/// connection left open for the next request.
fn get_kept(s: &mut TcpStream, path: &str) -> Reply {
    write!(s, "GET {path} HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
    let mut raw = Vec::new();
    let mut byte = [0u8; 1];
    while !raw.ends_with(b"\r\n\r\n") {
        assert_eq!(
            s.read(&mut byte).unwrap(),
            1,
            "{path}: the header block ends"
        );
        raw.push(byte[0]);
    }
    let end = raw.len() - 4;
    let head = String::from_utf8_lossy(&raw).to_ascii_lowercase();
    let len: usize = head
        .lines()
        .find_map(|l| l.strip_prefix("content-length:"))
        .expect("a length")
        .trim()
        .parse()
        .unwrap();
    let mut body = vec![0u8; len];
    s.read_exact(&mut body).unwrap();
    raw.extend(body);
    parse_reply(&raw, end, path)
}

fn parse_reply(raw: &[u8], end: usize, path: &str) -> Reply {
    let head = String::from_utf8(raw[..end].to_vec()).unwrap();
    let mut lines = head.split("\r\n");
    let status = lines
        .next()
        .unwrap()
        .split(' ')
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    let headers: Vec<(String, String)> = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(n, v)| (n.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect();
    let body = raw[end + 4..].to_vec();
    let reply = Reply {
        status,
        headers,
        body,
    };
    if let Some(len) = reply.header("content-length") {
        assert_eq!(len.parse::<usize>().unwrap(), reply.body.len(), "{path}");
    }
    reply
}

fn start(source: &str, points: u64) -> (RunningServer, Site) {
    start_with(source, points, 2)
}

fn start_with(source: &str, points: u64, workers: usize) -> (RunningServer, Site) {
    let opts = TileOptions {
        points,
        flame_samples: points,
        seed: 0,
    };
    let site = Site::load(source, opts).unwrap();
    let again = Site::load(source, opts).unwrap();
    let server = serve(
        site,
        &ServeOptions {
            host: "127.0.0.1".into(),
            port: 0,
            workers,
        },
    )
    .unwrap();
    (server, again)
}

/// Waits (at most `limit`) until `done` holds of the server's tile counts.
fn wait_for(
    server: &RunningServer,
    limit: Duration,
    done: impl Fn(&TileStats) -> bool,
) -> (TileStats, Duration) {
    let t = Instant::now();
    loop {
        let s = server.stats();
        if done(&s) || t.elapsed() > limit {
            return (s, t.elapsed());
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The tile's RGBA pixels, and how many are inked (opaque).
fn inked(reply: &Reply, what: &str) -> (image::RgbaImage, usize) {
    assert_eq!(reply.status, 200, "{what}: {}", reply.text());
    assert_eq!(reply.header("content-type"), Some("image/png"), "{what}");
    let img = image::load_from_memory(&reply.body).unwrap().to_rgba8();
    let n = img.pixels().filter(|p| p[3] == 255).count();
    assert!(
        img.pixels().all(|p| p[3] == 0 || p[3] == 255),
        "{what}: ink is opaque, the rest transparent"
    );
    (img, n)
}

/// Tile `(x, y)` of `level` holding the point `p` (row 0 at the top).
fn tile_of(site: &Site, level: u32, p: [f64; 2]) -> (u64, u64) {
    let base = site.tiling.base();
    let ts = base.size()[0] / (level as f64).exp2();
    (
        ((p[0] - base.min[0]) / ts).floor() as u64,
        ((base.max[1] - p[1]) / ts).floor() as u64,
    )
}

#[test]
fn tiles_of_sierpinski_at_the_top_and_2_to_the_20_deep() {
    let (server, site) = start("sierpinski", 400_000);
    let addr = server.addr();
    assert!(addr.ip().is_loopback());
    assert!(site.tiling.max_level() >= 30, "{}", site.tiling.max_level());

    let page = get(addr, "/");
    assert_eq!(page.status, 200);
    assert!(
        page.text().contains("\"sierpinski\""),
        "the page names its view"
    );
    assert!(page.text().contains("/viewer.js"));
    let script = get(addr, "/viewer.js");
    assert_eq!(script.status, 200);
    assert!(script.text().contains("requestAnimationFrame"));
    assert!(get(addr, "/LICENSE").text().contains("MIT"));

    let (_, top) = inked(&get(addr, "/tile/sierpinski?level=0&x=0&y=0"), "level 0");
    // The triangle at 75 % of 256 pixels: a quarter of its bounding box's pixels or more
    // (its dimension is 1.585: at 192 pixels, 3^7 sub-triangles of about 1.5 pixels).
    assert!(top > 192 * 166 / 8, "level 0: {top} pixels inked");

    // 2^20 deep on the triangle's left edge, from (0, 0) to (1/2, √3/2): a segment crossing
    // the tile, plus the sub-triangles along it.
    let h = 3f64.sqrt() / 2.0;
    let t = 0.3141592653589793;
    let (x, y) = tile_of(&site, 20, [0.5 * t, h * t]);
    let deep = get(
        addr,
        &format!("/tile/sierpinski?level=20&x={x}&y={y}&mode=density"),
    );
    let (_, n) = inked(&deep, "level 20");
    assert!(n >= 100, "level 20 tile ({x}, {y}): {n} pixels inked");

    // A tile the attractor misses is a tile: transparent, 200.
    let (img, n) = inked(
        &get(addr, "/tile/sierpinski?level=3&x=0&y=0"),
        "empty corner",
    );
    assert_eq!(
        (n, img.width()),
        (0, 256),
        "the top-left corner misses the triangle"
    );
    let (img, _) = inked(
        &get(addr, "/tile/sierpinski?level=3&x=0&y=0&size=64"),
        "64 px",
    );
    assert_eq!(img.dimensions(), (64, 64));
    server.stop();
}

/// A code whose attractor is the whole unit square (four maps of ratio 1/2): a tile 2²⁰
/// deep inside it is inked all over, so the deep-zoom sampler spreads its points over the
/// tile as the plain game would over the whole square.
#[test]
fn a_tile_2_to_the_20_deep_inside_a_filled_attractor_is_full() {
    let maps: Vec<Affine2> = [(0.0, 0.0), (0.5, 0.0), (0.0, 0.5), (0.5, 0.5)]
        .iter()
        .map(|&(e, f)| Affine2::new(0.5, 0.0, 0.0, 0.5, e, f))
        .collect();
    let mut code = IfsCode::from_affine2(Some("square"), &maps).unwrap();
    code.framing = Some(Window {
        min: [-0.25, -0.25],
        max: [1.25, 1.25],
    });
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("square.json");
    code.save(&path).unwrap();
    let (server, site) = start(path.to_str().unwrap(), 2_000_000);
    assert_eq!(
        site.tiling.base(),
        code.framing.unwrap(),
        "the code's framing is the base"
    );
    assert_eq!(site.tiling.max_level(), 32);
    let (x, y) = tile_of(&site, 20, [0.61803398875, 0.41421356237]);
    let (_, n) = inked(
        &get(server.addr(), &format!("/tile/square?level=20&x={x}&y={y}")),
        "inside",
    );
    assert!(n > 256 * 256 * 95 / 100, "{n} of 65536 pixels inked");
    // The deepest level renders too.
    let deepest = site.tiling.max_level();
    let (x, y) = tile_of(&site, deepest, [0.61803398875, 0.41421356237]);
    let (_, n) = inked(
        &get(
            server.addr(),
            &format!("/tile/square?level={deepest}&x={x}&y={y}"),
        ),
        "deepest",
    );
    assert!(
        n > 256 * 256 * 95 / 100,
        "level {deepest}: {n} of 65536 pixels inked"
    );
    server.stop();
}

#[test]
fn bad_tile_parameters_get_400_with_the_reason() {
    let (server, site) = start("sierpinski", 10_000);
    let addr = server.addr();
    let deepest = site.tiling.max_level();
    for (query, words) in [
        ("level=NaN&x=0&y=0", "`level`: must be a whole number"),
        ("level=inf&x=0&y=0", "`level`"),
        ("level=-3&x=0&y=0", "`level`"),
        ("level=0.5&x=0&y=0", "`level`"),
        (
            &format!("level={}&x=0&y=0", deepest + 1),
            "double-precision",
        ),
        ("level=2&x=4&y=0", "`x`: must be a whole number in 0..=3"),
        ("level=2&x=0&y=-1", "`y`"),
        ("level=2&x=0", "`y` is missing"),
        (
            "level=0&x=0&y=0&size=100000",
            "`size`: must be a whole number in 0..=512",
        ),
        ("level=0&x=0&y=0&size=8", "`size`"),
        ("level=0&x=0&y=0&mode=3d", "`mode`"),
        ("level=0&x=0&y=0&cmap=jet", "`cmap`"),
        (
            "level=0&x=0&y=0&zoom=1e300",
            "unknown tile parameter `zoom`",
        ),
        ("level=0&x=0&x=0&y=0", "given twice"),
    ] {
        let r = get(addr, &format!("/tile/sierpinski?{query}"));
        assert_eq!(r.status, 400, "{query}: {}", r.text());
        assert!(r.text().contains(words), "{query}: {}", r.text());
    }
    assert_eq!(get(addr, "/tile/fern?level=0&x=0&y=0").status, 404);
    assert_eq!(get(addr, "/../Cargo.toml").status, 404);
    server.stop();
}

/// The accept thread records each page's latest generation as requests arrive; a worker
/// skips a queued tile of an older one.
#[test]
fn a_tile_of_a_stale_generation_is_skipped() {
    let (server, _) = start("sierpinski", 10_000);
    let addr = server.addr();
    let fresh = get(addr, "/tile/sierpinski?level=1&x=0&y=0&gen=5&sid=77");
    assert_eq!(fresh.status, 200, "{}", fresh.text());
    let stale = get(addr, "/tile/sierpinski?level=1&x=1&y=0&gen=3&sid=77");
    assert_eq!(stale.status, 409, "{}", stale.text());
    assert!(stale.text().contains("stale"), "{}", stale.text());
    // Another page's generations are its own; a request without one is always drawn.
    assert_eq!(
        get(addr, "/tile/sierpinski?level=1&x=1&y=0&gen=0&sid=78").status,
        200
    );
    assert_eq!(get(addr, "/tile/sierpinski?level=1&x=1&y=1").status, 200);
    server.stop();
}

/// Requests from several clients at once are all answered.
#[test]
fn concurrent_tiles_are_all_served() {
    let (server, _) = start("fern", 200_000);
    let addr = server.addr();
    let threads: Vec<_> = (0..8u64)
        .map(|i| {
            std::thread::spawn(move || {
                get(addr, &format!("/tile/fern?level=3&x={}&y={}", i % 8, i / 2)).status
            })
        })
        .collect();
    for t in threads {
        assert_eq!(t.join().unwrap(), 200);
    }
    server.stop();
}

#[test]
fn a_run_folder_shows_target_and_recovered_code_side_by_side() {
    let dir = tempfile::tempdir().unwrap();
    let mut code = ifslab::model::library::builtin("sierpinski").unwrap();
    code.name = Some("recovered".into());
    code.framing = Some(Window {
        min: [-0.2, -0.3],
        max: [1.2, 1.1],
    });
    code.save(dir.path().join("code.json")).unwrap();
    let target = image::GrayImage::from_fn(32, 32, |x, y| image::Luma([((x * y) % 256) as u8]));
    target.save(dir.path().join("target.png")).unwrap();
    let loss = image::RgbImage::from_pixel(40, 20, image::Rgb([255, 0, 0]));
    loss.save(dir.path().join("loss.png")).unwrap();

    let (server, site) = start(dir.path().to_str().unwrap(), 10_000);
    let addr = server.addr();
    let names: Vec<&str> = site.views.iter().map(|v| v.name()).collect();
    assert_eq!(names, ["target", "recovered"]);
    let page = get(addr, "/").text();
    let info = get(addr, "/info.json");
    let info: serde_json::Value = serde_json::from_slice(&info.body).unwrap();
    for name in ["target", "recovered"] {
        assert!(
            page.contains(&format!("\"name\":\"{name}\"")),
            "{name} on the page"
        );
    }
    assert_eq!(info["views"][0]["kind"], "picture");
    assert_eq!(info["views"][1]["kind"], "tiles");
    assert_eq!(
        info["base"]["min"][0], -0.2,
        "the code's framing, made square"
    );
    assert_eq!(info["base"]["max"][1], 1.1);
    let picture = get(addr, info["views"][0]["url"].as_str().unwrap());
    assert_eq!(picture.status, 200);
    assert_eq!(
        picture.body,
        std::fs::read(dir.path().join("target.png")).unwrap()
    );
    let loss_url = info["loss"].as_str().unwrap();
    assert_eq!(get(addr, loss_url).status, 200);
    let tile = get(
        addr,
        &format!(
            "{}?level=0&x=0&y=0",
            info["views"][1]["url"].as_str().unwrap()
        ),
    );
    assert!(inked(&tile, "recovered").1 > 1000);
    server.stop();

    // A folder that is no run is refused with what to give instead.
    let empty = tempfile::tempdir().unwrap();
    let e = Site::load(empty.path().to_str().unwrap(), TileOptions::default()).unwrap_err();
    assert!(e.to_string().contains("without code.json"), "{e}");
}

/// A tile whose client leaves is not drawn on: a render under way stops at its next batch
/// of points, and tiles still queued are skipped. One worker, tiles of 10⁸ points (0.43 s
/// each on two idle cores, the most points a tile may have): the two queued behind the
/// first are dropped 180 ms in, the first 80 ms later, well before it is drawn.
#[test]
fn a_client_that_leaves_cancels_its_tile() {
    let (server, _) = start_with("sierpinski", 100_000_000, 1);
    let addr = server.addr();
    let ask = |x: u32| {
        let mut s = TcpStream::connect(addr).unwrap();
        write!(
            s,
            "GET /tile/sierpinski?level=2&x={x}&y=3 HTTP/1.1\r\nHost: x\r\n\r\n"
        )
        .unwrap();
        s
    };
    let first = ask(0);
    std::thread::sleep(Duration::from_millis(100));
    let queued = [ask(1), ask(2)];
    std::thread::sleep(Duration::from_millis(80));
    drop(queued);
    // The queued tiles' watchers (every 20 ms) see their clients gone before the worker is
    // free: dropped together, a loaded machine could let the worker pick up a queued tile
    // before its watcher had looked, and draw some of it.
    std::thread::sleep(Duration::from_millis(80));
    drop(first);
    let (stats, took) = wait_for(&server, Duration::from_secs(20), |s| {
        s.cancelled_drawing + s.cancelled_queued == 3
    });
    assert_eq!(
        stats,
        TileStats {
            drawn: 0,
            cancelled_queued: 2,
            cancelled_drawing: 1,
            stale: 0,
        },
        "after {took:?}"
    );
    assert!(
        took < Duration::from_secs(1),
        "the render stopped {took:?} after its client left"
    );
    eprintln!("the render stopped {took:?} after its client left");
    let stats: serde_json::Value = serde_json::from_slice(&get(addr, "/stats.json").body).unwrap();
    assert_eq!(stats["cancelled_drawing"], 1);
    server.stop();
}

/// A render under way for a page that has moved to a newer generation stops, and its
/// client hears 409.
#[test]
fn a_tile_of_a_stale_generation_stops_midway() {
    let (server, _) = start_with("sierpinski", 100_000_000, 2);
    let addr = server.addr();
    let old = std::thread::spawn(move || {
        let t = Instant::now();
        let r = get(addr, "/tile/sierpinski?level=1&x=0&y=1&gen=1&sid=42");
        (r.status, r.text(), t.elapsed())
    });
    std::thread::sleep(Duration::from_millis(300));
    let mut newer = TcpStream::connect(addr).unwrap();
    write!(
        newer,
        "GET /tile/sierpinski?level=1&x=1&y=1&gen=2&sid=42 HTTP/1.1\r\nHost: x\r\n\r\n"
    )
    .unwrap();
    let (status, text, took) = old.join().unwrap();
    assert_eq!(status, 409, "{text}");
    assert!(text.contains("stale"), "{text}");
    // A render that ran to its end would have been answered 200 (drawn is drawn).
    eprintln!("the stale tile was answered 409 after {took:?}");
    drop(newer);
    // The newer tile is drawn or cancelled (its client left), whichever comes first on a
    // busy machine; the stale one is neither.
    let (stats, _) = wait_for(&server, Duration::from_secs(30), |s| {
        s.drawn + s.cancelled_drawing == 1
    });
    assert_eq!((stats.stale, stats.drawn + stats.cancelled_drawing), (1, 1));
    server.stop();
}

/// Kept-alive connections never wait for one another. tiny_http 0.12 (which this server
/// ran on first) could leave a connection accepted just after another one queued until
/// some connection closed — with a browser's six kept open, for minutes. Here 20 rounds
/// of six connections opened at once (a browser's burst), each asking for three tiles one
/// after the other on its kept-alive connection, beside 12 idle kept-alive connections: no
/// answer may take more than 3 s.
#[test]
fn kept_alive_connections_never_wait_for_one_another() {
    let (server, _) = start_with("sierpinski", 20_000, 2);
    let addr = server.addr();
    let mut idle: Vec<TcpStream> = Vec::new();
    for _ in 0..12 {
        let mut s = TcpStream::connect(addr).unwrap();
        assert_eq!(get_kept(&mut s, "/info.json").status, 200);
        idle.push(s);
    }
    let mut slowest = Duration::ZERO;
    for round in 0..20u32 {
        let burst: Vec<_> = (0..6u32)
            .map(|c| {
                std::thread::spawn(move || {
                    let mut s = TcpStream::connect(addr).unwrap();
                    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
                    let mut slowest = Duration::ZERO;
                    for k in 0..3u32 {
                        let t = Instant::now();
                        let path = format!(
                            "/tile/sierpinski?level=3&x={}&y={}&size=32",
                            (round + c) % 8,
                            k
                        );
                        let r = get_kept(&mut s, &path);
                        assert_eq!(r.status, 200, "{path}");
                        assert_eq!(r.header("connection"), Some("keep-alive"));
                        slowest = slowest.max(t.elapsed());
                    }
                    slowest
                })
            })
            .collect();
        for b in burst {
            slowest = slowest.max(b.join().expect("every answer within the read timeout"));
        }
    }
    assert!(
        slowest < Duration::from_secs(3),
        "slowest answer {slowest:?}"
    );
    eprintln!("slowest of 360 answers on kept-alive connections: {slowest:?}");
    // The idle ones still answer.
    for s in &mut idle {
        assert_eq!(get_kept(s, "/viewer.css").status, 200);
    }
    server.stop();
}

/// Requests the server does not take are refused with a status and a reason.
#[test]
fn requests_other_than_get_are_refused() {
    let (server, _) = start("sierpinski", 10_000);
    let addr = server.addr();
    for (raw, status) in [
        ("POST / HTTP/1.1\r\nContent-Length: 3\r\n\r\nabc", 413),
        ("DELETE / HTTP/1.1\r\n\r\n", 405),
        ("GET / HTTP/3\r\n\r\n", 505),
        ("GET nothing\r\n\r\n", 400),
    ] {
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        s.write_all(raw.as_bytes()).unwrap();
        let mut out = String::new();
        let _ = s.read_to_string(&mut out);
        assert!(
            out.starts_with(&format!("HTTP/1.1 {status} ")),
            "{raw:?}: {out}"
        );
    }
    server.stop();
}

/// The single flame of a `.flame` file, in tiles of the flame renderer: the top tile is
/// `ifslab flame render --size 256 256 --quality Q` of it to the byte, a tile one level down
/// is the quadrant of the 512² render with the same samples (the same chaos game, another
/// camera), and the levels stop where the samples per pixel fall under one.
#[test]
fn a_flames_tiles_are_the_flame_renderers_pictures() {
    use ifslab::model::flame::read_flames;
    use ifslab::render::flame::{FlameRenderConfig, render_flame};
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let file = repo.join("paper_repro/fractal_flames/results/fig4_heart/learned.flame");
    let mut flame = read_flames(&file).unwrap().remove(0);
    assert_eq!((flame.size, flame.center), ([400, 400], [0.0, 0.0]));
    flame.quality = 8.0;
    flame.rotate = 30.0;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("heart.flame");
    ifslab::model::flame::write_flames(&path, std::slice::from_ref(&flame)).unwrap();
    // 65536 × 32 samples a tile: 32 per pixel at the top, 2 at level 2, ½ at level 3.
    let samples = 65536 * 32;
    let (server, site) = start_with(path.to_str().unwrap(), samples, 2);
    let addr = server.addr();
    assert_eq!(site.tiling.max_level(), 2);
    let info: serde_json::Value = serde_json::from_slice(&get(addr, "/info.json").body).unwrap();
    assert_eq!(info["modes"], serde_json::json!(["colour"]));
    assert!(
        info["note"].as_str().unwrap().contains("down to level 2"),
        "{}",
        info["note"]
    );
    let url = info["views"][0]["url"].as_str().unwrap().to_string();
    let tile = |q: &str| {
        let r = get(addr, &format!("{url}?{q}"));
        assert_eq!(r.status, 200, "{q}: {}", r.text());
        image::load_from_memory(&r.body).unwrap().to_rgba8()
    };
    let cfg = FlameRenderConfig::default();
    let framed = |size: u32, quality: f64| {
        let mut f = flame.clone();
        f.scale *= size as f64 / 400.0;
        f.size = [size, size];
        f.quality = quality;
        render_flame(&f, &cfg, None).unwrap()
    };
    // Level 0: quality 8 (under the 32 the samples allow).
    let top = tile("level=0&x=0&y=0");
    assert_eq!(top.as_raw(), &framed(256, 8.0).to_rgba8(false), "level 0");
    // Level 1, the top-right quadrant: quality 32 on 256² = quality 8 on 512².
    let quarter = tile("level=1&x=1&y=0");
    let whole = framed(512, 8.0).to_rgba8(false);
    let mut differ = 0usize;
    let mut colours = std::collections::HashSet::new();
    for y in 0..256usize {
        for x in 0..256usize {
            let a = &quarter.as_raw()[4 * (y * 256 + x)..][..3];
            let b = &whole[4 * (y * 512 + 256 + x)..][..3];
            differ += a.iter().zip(b).any(|(p, q)| p.abs_diff(*q) > 2) as usize;
            colours.insert([b[0], b[1], b[2]]);
        }
    }
    assert!(
        colours.len() > 100,
        "{} colours in the quadrant",
        colours.len()
    );
    assert!(differ * 200 < 65536, "{differ} of 65536 pixels differ");
    eprintln!(
        "flame tile (1, 1, 0) against the 512² render's quadrant: {differ} of 65536 pixels differ, {} colours",
        colours.len()
    );
    // Deeper than the density bound, and another view's mode, are refused.
    assert_eq!(get(addr, &format!("{url}?level=3&x=0&y=0")).status, 400);
    let r = get(addr, &format!("{url}?level=0&x=0&y=0&mode=density"));
    assert_eq!(r.status, 400);
    assert!(r.text().contains("`colour` for this view"), "{}", r.text());
    server.stop();
}

/// A render whose progress says it is cancelled ends with `Error::Cancelled`, for a
/// code's tiles and a flame's alike, before drawing its points.
#[test]
fn renders_stop_when_cancelled() {
    struct Cancelled;
    impl ifslab::progress::Progress for Cancelled {
        fn cancelled(&self) -> bool {
            true
        }
    }
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let flame = repo.join("paper_repro/fractal_flames/results/fig1_wisteria/learned.flame");
    for source in ["sierpinski", flame.to_str().unwrap()] {
        let site = Site::load(
            source,
            TileOptions {
                points: 100_000_000,
                flame_samples: 100_000_000,
                seed: 0,
            },
        )
        .unwrap();
        let ifslab_experiments::serve::View::Tiles { renderer, .. } = site.views.last().unwrap()
        else {
            panic!("{source}: a tiled view");
        };
        let req = ifslab_experiments::serve::TileRequest::parse(
            "level=0&x=0&y=0",
            &site.tiling,
            renderer.modes(),
        )
        .unwrap();
        let t = Instant::now();
        let e = renderer.render_png(&req, &Cancelled).unwrap_err();
        assert!(
            matches!(e.as_core(), Some(ifslab::Error::Cancelled(_))),
            "{source}: {e:#}"
        );
        assert!(
            t.elapsed() < Duration::from_secs(1),
            "{source}: {:?}",
            t.elapsed()
        );
    }
}
