//! The HTTP side of `ifslab serve` ([`super::http`]: HTTP/1.1 on the standard library's
//! sockets, a thread per connection, no async runtime).
//!
//! A connection's thread answers what costs nothing there — the page, its script, pictures,
//! tiles already drawn, refusals — and queues tiles to draw for a pool of worker threads
//! (each render runs on the renderer's own thread pool too), then waits for its tile.
//!
//! **Cancelled tiles.** A tile the page no longer needs is not drawn, or stops being drawn
//! midway, in two ways:
//! - *the client leaves*: when the page moves on it aborts the requests of tiles it no
//!   longer shows, and the browser closes their connections. The thread waiting for a tile
//!   looks at its socket every [`WATCH`]; once the client has closed it, the tile's cancel
//!   flag is set: a worker that has not started it skips it, and a render under way stops
//!   at its next batch of points (the renderers poll [`ifslab::progress::Progress::cancelled`]:
//!   about 1/128 of a tile's points for a code, one trajectory of 10 000 for a flame).
//! - *stale generations*: each pan or zoom starts a new generation of the page, and every
//!   tile request carries the page's id (`sid`, drawn when the page loads) and its
//!   generation (`gen`). The latest generation seen per page is recorded as requests
//!   arrive; a tile of an older generation is not started, or is stopped, and answered
//!   `409 Conflict` ("stale"); the page asks again, under its current generation, for the
//!   tiles it still shows. Tiles without `gen` and `sid` are never stale.
//!
//! `/stats.json` counts tiles drawn, cancelled before and during their render, and stale.

use std::collections::{HashMap, VecDeque};
use std::net::{IpAddr, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{RecvTimeoutError, Sender, channel};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use crate::error::Context;

use super::http::{self, Conn, ReadError, Response};
use super::tile::TileRequest;
use super::{Site, View};
mod work;
pub use work::TileStats;
use work::{Job, Queue, Shared, Stats, TileCache, lock, work};

/// The page, its script and style sheet, and the viewer's licence, compiled in.
const PAGE: &str = include_str!("../../../assets/viewer/index.html");
const SCRIPT: &str = include_str!("../../../assets/viewer/viewer.js");
const STYLE: &str = include_str!("../../../assets/viewer/viewer.css");
const LICENSE: &str = include_str!("../../../assets/viewer/LICENSE");
/// Where the page's info goes in `index.html`.
const INFO_SLOT: &str = "/*IFSLAB_INFO*/null";

/// Most bytes of drawn tiles kept to answer again at once.
const CACHE_BYTES: usize = 64 << 20;
/// Most pages whose latest generation is remembered (then forgotten all at once).
const MAX_PAGES: usize = 4096;
/// How often a connection waiting for its tile looks whether its client is still there.
pub const WATCH: Duration = Duration::from_millis(20);

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
    shared: Arc<Shared>,
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

    /// What the tile workers did so far.
    pub fn stats(&self) -> TileStats {
        self.shared.stats.snapshot()
    }

    /// Serves until the process ends.
    pub fn wait(self) {
        let _ = self.accept.join();
        for w in self.workers {
            let _ = w.join();
        }
    }

    /// Stops accepting, lets the workers finish the tiles queued, and returns (open
    /// connections close within [`http::POLL`] once idle).
    pub fn stop(self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        // Wakes the accept loop.
        let _ = TcpStream::connect_timeout(&self.addr, Duration::from_secs(1));
        let _ = self.accept.join();
        lock(&self.shared.queue).closed = true;
        self.shared.ready.notify_all();
        for w in self.workers {
            let _ = w.join();
        }
    }
}

/// Starts serving `site`: binds, then answers on background threads; returns at once.
pub fn serve(site: Site, opts: &ServeOptions) -> crate::Result<RunningServer> {
    let ip = opts
        .host
        .parse::<IpAddr>()
        .map_err(|e| crate::Error::invalid(e.to_string()))
        .with_context(|| {
            format!(
                "--host must be an IP address (127.0.0.1 for this machine only), got `{}`",
                opts.host
            )
        })?;
    if opts.workers == 0 {
        crate::error::bail!("--workers must be at least 1");
    }
    let listener = TcpListener::bind(SocketAddr::new(ip, opts.port))
        .with_context(|| format!("cannot listen on {}:{}", opts.host, opts.port))?;
    let addr = listener.local_addr()?;
    let info = serde_json::to_string(&site.info())?;
    // JSON inside a script element: `<` escaped so no `</script>` can end it.
    let page = PAGE.replacen(INFO_SLOT, &info.replace('<', "\\u003c"), 1);
    let shared = Arc::new(Shared {
        site,
        page,
        info,
        generations: Mutex::new(HashMap::new()),
        cache: Mutex::new(TileCache::default()),
        queue: Mutex::new(Queue::default()),
        ready: Condvar::new(),
        stop: AtomicBool::new(false),
        connections: AtomicUsize::new(0),
        stats: Stats::default(),
    });
    let workers = (0..opts.workers)
        .map(|i| {
            let shared = shared.clone();
            std::thread::Builder::new()
                .name(format!("ifslab-serve-{i}"))
                .spawn(move || work(&shared))
        })
        .collect::<std::io::Result<Vec<_>>>()?;
    let accept = {
        let shared = shared.clone();
        std::thread::Builder::new()
            .name("ifslab-serve-accept".into())
            .spawn(move || accept(listener, shared))?
    };
    Ok(RunningServer {
        shared,
        addr,
        accept,
        workers,
    })
}

/// Gives each connection its own thread, at once.
fn accept(listener: TcpListener, shared: Arc<Shared>) {
    for stream in listener.incoming() {
        if shared.stop.load(Ordering::SeqCst) {
            return;
        }
        let Ok(stream) = stream else { continue };
        if shared.connections.fetch_add(1, Ordering::SeqCst) >= http::MAX_CONNECTIONS {
            shared.connections.fetch_sub(1, Ordering::SeqCst);
            if let Ok(mut c) = Conn::new(stream) {
                let busy = format!("more than {} connections are open", http::MAX_CONNECTIONS);
                c.respond(&Response::text(503, &busy), false, true);
            }
            continue;
        }
        let s = shared.clone();
        let spawned = std::thread::Builder::new()
            .name("ifslab-serve-conn".into())
            .spawn(move || {
                connection(stream, &s);
                s.connections.fetch_sub(1, Ordering::SeqCst);
            });
        if spawned.is_err() {
            shared.connections.fetch_sub(1, Ordering::SeqCst);
        }
    }
}

/// Answers a connection's requests one after the other until it closes.
fn connection(stream: TcpStream, shared: &Shared) {
    let Ok(mut conn) = Conn::new(stream) else {
        return;
    };
    let stop = || shared.stop.load(Ordering::SeqCst);
    loop {
        let head = match conn.read_head(&stop) {
            Ok(h) => h,
            Err(ReadError::Closed) => return,
            Err(ReadError::Bad(status, why)) => {
                conn.respond(&Response::text(status, why), false, true);
                return;
            }
        };
        let response = match head.method.as_str() {
            "GET" | "HEAD" => route(&head.target, shared, conn.stream()),
            _ => Some(Response::text(405, "only GET is served")),
        };
        // None: the client left while its tile was drawn.
        let Some(response) = response else { return };
        let keep = head.keep_alive && !stop();
        if !conn.respond(&response, keep, head.method != "HEAD") || !keep {
            return;
        }
    }
}

fn png(body: Vec<u8>) -> Response {
    Response::new(200, "image/png", body)
}

/// The answer to `target`; `None` when the client left before its tile was drawn.
fn route(target: &str, shared: &Shared, stream: &TcpStream) -> Option<Response> {
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    let site = &shared.site;
    let r = match path {
        "/" | "/index.html" => Response::new(
            200,
            "text/html; charset=utf-8",
            shared.page.clone().into_bytes(),
        ),
        "/viewer.js" => Response::new(
            200,
            "text/javascript; charset=utf-8",
            SCRIPT.as_bytes().to_vec(),
        ),
        "/viewer.css" => Response::new(200, "text/css; charset=utf-8", STYLE.as_bytes().to_vec()),
        "/LICENSE" => Response::text(200, LICENSE),
        "/info.json" => Response::new(200, "application/json", shared.info.clone().into_bytes()),
        "/stats.json" => Response::new(
            200,
            "application/json",
            serde_json::to_vec(&shared.stats.snapshot()).unwrap_or_default(),
        ),
        "/picture/loss.png" if site.loss.is_some() => png(site.loss.clone().unwrap_or_default()),
        _ => {
            if let Some(name) = path
                .strip_prefix("/picture/")
                .and_then(|p| p.strip_suffix(".png"))
                && let Some(View::Picture { png: bytes, .. }) = site.view(name)
            {
                return Some(png(bytes.clone()));
            }
            if let Some(name) = path.strip_prefix("/tile/")
                && let Some(view) = site
                    .views
                    .iter()
                    .position(|v| v.name() == name && matches!(v, View::Tiles { .. }))
            {
                return route_tile(view, query, shared, stream);
            }
            Response::text(404, &format!("nothing at {}", path.escape_debug()))
        }
    };
    Some(r)
}

fn route_tile(view: usize, query: &str, shared: &Shared, stream: &TcpStream) -> Option<Response> {
    let View::Tiles { renderer, .. } = &shared.site.views[view] else {
        return Some(Response::text(500, "not a tiled view"));
    };
    let tile = match TileRequest::parse(query, &shared.site.tiling, renderer.modes()) {
        Ok(t) => t,
        Err(e) => return Some(Response::text(400, &e.to_string())),
    };
    let key = format!("{view}/{}", tile.key());
    if let Some(bytes) = lock(&shared.cache).get(&key) {
        return Some(png(bytes.to_vec()));
    }
    if let Some((sid, generation)) = tile.generation {
        let mut seen = lock(&shared.generations);
        if seen.len() >= MAX_PAGES && !seen.contains_key(&sid) {
            seen.clear();
        }
        let latest = seen.entry(sid).or_insert(generation);
        *latest = (*latest).max(generation);
    }
    let (reply, answer) = channel();
    let cancel = Arc::new(AtomicBool::new(false));
    {
        let mut q = lock(&shared.queue);
        if q.closed {
            return Some(Response::text(503, "the tile workers have stopped"));
        }
        q.jobs.push_back(Job {
            view,
            tile,
            cancel: cancel.clone(),
            reply,
        });
    }
    shared.ready.notify_one();
    loop {
        match answer.recv_timeout(WATCH) {
            Ok(r) => return Some(r),
            Err(RecvTimeoutError::Timeout) => {
                if http::client_gone(stream) {
                    cancel.store(true, Ordering::SeqCst);
                    return None;
                }
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Some(Response::text(500, "the tile's worker ended without it"));
            }
        }
    }
}
