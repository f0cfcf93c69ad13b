//! The HTTP side of `ifslab serve` (`tiny_http`: a blocking server without an async runtime,
//! a few small crates on top of the standard library).
//!
//! One thread accepts requests and answers what costs nothing there — the page, its script,
//! pictures, tiles already drawn, refusals — and queues tiles to draw for a pool of worker
//! threads (each render runs on the renderer's own thread pool too).
//!
//! **Stale tiles.** The page numbers its views: each pan or zoom starts a new generation,
//! and every tile request carries the page's id (`sid`, drawn when the page loads) and the
//! generation it was asked for (`gen`). The accept thread records the latest generation
//! seen per page; a worker that takes from the queue a tile of an older generation of its
//! page does not draw it and answers `409 Conflict` ("stale"), and the page asks again,
//! under its current generation, for the tiles it still shows. So a fast pan or a wheel
//! spin costs the tiles of the view it ends on, not of every view it passed. Tiles without
//! `gen` and `sid` are always drawn. A tile is not stopped halfway: at the default million
//! points it takes tens of milliseconds.
//!
//! **A known flaw of tiny_http 0.12.** Its pool of connection threads has a race: a
//! connection accepted while an idle thread is being woken for another one can wait in the
//! pool's queue until some connection closes — and a browser keeps its connections open
//! (Chromium: up to six per server, about five minutes idle). Measured with headless
//! Chromium on the browser test: in 3 of 12 page loads a tile was still unanswered after
//! 120 s (one came after 313 s). The page works around it by asking again for a tile not answered in 6 s (an
//! aborted request closes its connection, which frees the queued one); a server that
//! answers `Connection: close` (tiny_http does not let a response say so) or a pool without
//! the race would remove it.

use std::collections::{HashMap, VecDeque};
use std::net::{IpAddr, SocketAddr};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;

use anyhow::Context;
use tiny_http::{Header, Method, Request, Response};

use super::tile::TileRequest;
use super::{Site, View};

/// The page, its script and style sheet, and the viewer's licence, compiled in.
const PAGE: &str = include_str!("../../assets/viewer/index.html");
const SCRIPT: &str = include_str!("../../assets/viewer/viewer.js");
const STYLE: &str = include_str!("../../assets/viewer/viewer.css");
const LICENSE: &str = include_str!("../../assets/viewer/LICENSE");
/// Where the page's info goes in `index.html`.
const INFO_SLOT: &str = "/*IFSLAB_INFO*/null";

/// Most bytes of drawn tiles kept to answer again at once.
const CACHE_BYTES: usize = 64 << 20;
/// Most pages whose latest generation is remembered (then forgotten all at once).
const MAX_PAGES: usize = 4096;

/// Where and how to serve.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ServeOptions {
    /// The address to listen on: an IP address, `127.0.0.1` (this machine only) by default.
    pub host: String,
    /// The port; 0 picks a free one ([`RunningServer::addr`] says which).
    pub port: u16,
    /// Threads drawing tiles (at least 1).
    pub workers: usize,
}

impl Default for ServeOptions {
    fn default() -> Self {
        ServeOptions {
            host: "127.0.0.1".into(),
            port: 8080,
            workers: std::thread::available_parallelism()
                .map_or(2, |n| n.get())
                .clamp(2, 8),
        }
    }
}

/// A server started by [`serve`]: its address, and its threads until [`RunningServer::stop`].
pub struct RunningServer {
    server: Arc<tiny_http::Server>,
    addr: SocketAddr,
    accept: JoinHandle<()>,
    workers: Vec<JoinHandle<()>>,
}

impl RunningServer {
    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The page's address.
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// Serves until the process ends.
    pub fn wait(self) {
        let _ = self.accept.join();
        for w in self.workers {
            let _ = w.join();
        }
    }

    /// Stops accepting, lets the workers finish the tiles queued, and returns.
    pub fn stop(self) {
        self.server.unblock();
        self.wait();
    }
}

/// A tile waiting for a worker.
struct Job {
    request: Request,
    view: usize,
    tile: TileRequest,
}

/// What the accept thread and the workers share.
struct Shared {
    site: Site,
    page: String,
    info: String,
    /// Latest generation seen per page id.
    generations: Mutex<HashMap<u64, u64>>,
    cache: Mutex<TileCache>,
}

/// Drawn tiles by view and request key, oldest forgotten first.
#[derive(Default)]
struct TileCache {
    tiles: HashMap<String, Arc<Vec<u8>>>,
    order: VecDeque<String>,
    bytes: usize,
}

impl TileCache {
    fn get(&self, key: &str) -> Option<Arc<Vec<u8>>> {
        self.tiles.get(key).cloned()
    }

    fn insert(&mut self, key: String, png: Arc<Vec<u8>>) {
        if self.tiles.contains_key(&key) {
            return;
        }
        self.bytes += png.len();
        self.order.push_back(key.clone());
        self.tiles.insert(key, png);
        while self.bytes > CACHE_BYTES {
            let Some(old) = self.order.pop_front() else {
                break;
            };
            if let Some(t) = self.tiles.remove(&old) {
                self.bytes -= t.len();
            }
        }
    }
}

/// A lock whose holder panicked still guards consistent data here (maps and a queue updated
/// in single calls).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Starts serving `site`: binds, then answers on background threads; returns at once.
pub fn serve(site: Site, opts: &ServeOptions) -> anyhow::Result<RunningServer> {
    let ip: IpAddr = opts.host.parse().with_context(|| {
        format!(
            "--host must be an IP address (127.0.0.1 for this machine only), got `{}`",
            opts.host
        )
    })?;
    if opts.workers == 0 {
        anyhow::bail!("--workers must be at least 1");
    }
    let server = tiny_http::Server::http(SocketAddr::new(ip, opts.port))
        .map_err(|e| anyhow::anyhow!("cannot listen on {}:{}: {e}", opts.host, opts.port))?;
    let addr = server
        .server_addr()
        .to_ip()
        .context("the server listens on an IP address")?;
    let server = Arc::new(server);
    let info = serde_json::to_string(&site.info())?;
    // JSON inside a script element: `<` escaped so no `</script>` can end it.
    let page = PAGE.replacen(INFO_SLOT, &info.replace('<', "\\u003c"), 1);
    let shared = Arc::new(Shared {
        site,
        page,
        info,
        generations: Mutex::new(HashMap::new()),
        cache: Mutex::new(TileCache::default()),
    });
    let (tx, rx) = channel::<Job>();
    let rx = Arc::new(Mutex::new(rx));
    let workers = (0..opts.workers)
        .map(|i| {
            let (shared, rx) = (shared.clone(), rx.clone());
            std::thread::Builder::new()
                .name(format!("ifslab-serve-{i}"))
                .spawn(move || work(&shared, &rx))
        })
        .collect::<std::io::Result<Vec<_>>>()?;
    let accept = {
        let (server, shared) = (server.clone(), shared.clone());
        std::thread::Builder::new()
            .name("ifslab-serve-accept".into())
            .spawn(move || {
                for request in server.incoming_requests() {
                    route(request, &shared, &tx);
                }
            })?
    };
    Ok(RunningServer {
        server,
        addr,
        accept,
        workers,
    })
}

fn header(name: &str, value: &str) -> Header {
    Header::from_bytes(name.as_bytes(), value.as_bytes()).expect("fixed ASCII header")
}

fn respond(request: Request, status: u16, content_type: &str, body: Vec<u8>) {
    // Lengths are known: no chunked encoding.
    let response = Response::from_data(body)
        .with_chunked_threshold(usize::MAX)
        .with_status_code(status)
        .with_header(header("Content-Type", content_type));
    let response = match (status, content_type) {
        (200, "image/png") => response.with_header(header("Cache-Control", "max-age=3600")),
        _ => response.with_header(header("Cache-Control", "no-store")),
    };
    // A page that went away is no error of the server's.
    let _ = request.respond(response);
}

fn text(request: Request, status: u16, message: &str) {
    respond(
        request,
        status,
        "text/plain; charset=utf-8",
        format!("{message}\n").into_bytes(),
    );
}

/// Answers `request` or queues it for a worker.
fn route(request: Request, shared: &Shared, queue: &Sender<Job>) {
    if *request.method() != Method::Get {
        return text(request, 405, "only GET is served");
    }
    let url = request.url().to_string();
    let (path, query) = url.split_once('?').unwrap_or((&url, ""));
    let site = &shared.site;
    match path {
        "/" | "/index.html" => {
            let page = shared.page.clone().into_bytes();
            respond(request, 200, "text/html; charset=utf-8", page)
        }
        "/viewer.js" => respond(
            request,
            200,
            "text/javascript; charset=utf-8",
            SCRIPT.as_bytes().to_vec(),
        ),
        "/viewer.css" => respond(
            request,
            200,
            "text/css; charset=utf-8",
            STYLE.as_bytes().to_vec(),
        ),
        "/LICENSE" => text(request, 200, LICENSE),
        "/info.json" => {
            let info = shared.info.clone().into_bytes();
            respond(request, 200, "application/json", info)
        }
        "/picture/loss.png" if site.loss.is_some() => {
            let png = site.loss.clone().unwrap_or_default();
            respond(request, 200, "image/png", png)
        }
        _ => {
            if let Some(name) = path
                .strip_prefix("/picture/")
                .and_then(|p| p.strip_suffix(".png"))
                && let Some(View::Picture { png, .. }) = site.view(name)
            {
                return respond(request, 200, "image/png", png.clone());
            }
            if let Some(name) = path.strip_prefix("/tile/")
                && let Some(view) = site
                    .views
                    .iter()
                    .position(|v| v.name() == name && matches!(v, View::Tiles { .. }))
            {
                return route_tile(request, view, query, shared, queue);
            }
            text(request, 404, &format!("nothing at {}", path.escape_debug()))
        }
    }
}

fn route_tile(request: Request, view: usize, query: &str, shared: &Shared, queue: &Sender<Job>) {
    let tile = match TileRequest::parse(query, &shared.site.tiling) {
        Ok(t) => t,
        Err(e) => return text(request, 400, &e.to_string()),
    };
    let key = format!("{view}/{}", tile.key());
    if let Some(png) = lock(&shared.cache).get(&key) {
        return respond(request, 200, "image/png", png.to_vec());
    }
    if let Some((sid, generation)) = tile.generation {
        let mut seen = lock(&shared.generations);
        if seen.len() >= MAX_PAGES && !seen.contains_key(&sid) {
            seen.clear();
        }
        let latest = seen.entry(sid).or_insert(generation);
        *latest = (*latest).max(generation);
    }
    if let Err(e) = queue.send(Job {
        request,
        view,
        tile,
    }) {
        // Only when every worker has ended.
        text(e.0.request, 503, "the tile workers have stopped");
    }
}

/// A worker: draws queued tiles until the queue closes.
fn work(shared: &Shared, queue: &Mutex<Receiver<Job>>) {
    loop {
        let job = lock(queue).recv();
        let Ok(Job {
            request,
            view,
            tile,
        }) = job
        else {
            return;
        };
        if let Some((sid, generation)) = tile.generation {
            let latest = lock(&shared.generations).get(&sid).copied();
            if let Some(latest) = latest
                && latest > generation
            {
                text(
                    request,
                    409,
                    &format!(
                        "stale: generation {generation} of page {sid} is older than {latest}, \
                         the latest it asked for; not drawn"
                    ),
                );
                continue;
            }
        }
        let View::Tiles { renderer, .. } = &shared.site.views[view] else {
            text(request, 500, "not a tiled view");
            continue;
        };
        // A panic in a render costs its tile, not the worker.
        let drawn =
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| renderer.render_png(&tile)));
        match drawn {
            Ok(Ok(png)) => {
                let png = Arc::new(png);
                lock(&shared.cache).insert(format!("{view}/{}", tile.key()), png.clone());
                respond(request, 200, "image/png", png.to_vec());
            }
            Ok(Err(e)) => text(request, 500, &format!("the tile was not drawn: {e:#}")),
            Err(_) => text(request, 500, "the tile's render panicked"),
        }
    }
}
