//! The drawing side of the server: the queue of tiles to draw, the worker threads that draw them, the cache of drawn tiles, the counters, and the watch that cancels a tile its client has left.

use super::*;

/// What the tile workers did: tiles drawn, tiles cancelled before a worker took them up or
/// while one drew them (their clients left), tiles of stale generations.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct TileStats {
    /// Drawn and sent.
    pub drawn: u64,
    /// Skipped: the client had left before a worker took the tile up.
    pub cancelled_queued: u64,
    /// Stopped midway: the client left while the tile was drawn.
    pub cancelled_drawing: u64,
    /// Not drawn, or stopped, because their page had moved to a newer generation.
    pub stale: u64,
}

#[derive(Default)]
pub(super) struct Stats {
    pub(super) drawn: AtomicU64,
    pub(super) cancelled_queued: AtomicU64,
    pub(super) cancelled_drawing: AtomicU64,
    pub(super) stale: AtomicU64,
}

impl Stats {
    pub(super) fn snapshot(&self) -> TileStats {
        TileStats {
            drawn: self.drawn.load(Ordering::SeqCst),
            cancelled_queued: self.cancelled_queued.load(Ordering::SeqCst),
            cancelled_drawing: self.cancelled_drawing.load(Ordering::SeqCst),
            stale: self.stale.load(Ordering::SeqCst),
        }
    }
}

pub(super) fn bump(c: &AtomicU64) {
    c.fetch_add(1, Ordering::SeqCst);
}

/// A tile waiting for a worker, and where its answer goes.
pub(super) struct Job {
    pub(super) view: usize,
    pub(super) tile: TileRequest,
    pub(super) cancel: Arc<AtomicBool>,
    pub(super) reply: Sender<Response>,
}

#[derive(Default)]
pub(super) struct Queue {
    pub(super) jobs: VecDeque<Job>,
    pub(super) closed: bool,
}

/// What the connections and the workers share.
pub(super) struct Shared {
    pub(super) site: Site,
    pub(super) page: String,
    pub(super) info: String,
    /// Latest generation seen per page id.
    pub(super) generations: Mutex<HashMap<u64, u64>>,
    pub(super) cache: Mutex<TileCache>,
    pub(super) queue: Mutex<Queue>,
    pub(super) ready: Condvar,
    pub(super) stop: AtomicBool,
    pub(super) connections: AtomicUsize,
    pub(super) stats: Stats,
}

impl Shared {
    /// The latest generation page `sid` asked for, if newer than `generation`.
    pub(super) fn newer(&self, generation: Option<(u64, u64)>) -> Option<u64> {
        let (sid, generation) = generation?;
        let latest = lock(&self.generations).get(&sid).copied()?;
        (latest > generation).then_some(latest)
    }
}

/// Drawn tiles by view and request key, oldest forgotten first.
#[derive(Default)]
pub(super) struct TileCache {
    pub(super) tiles: HashMap<String, Arc<Vec<u8>>>,
    pub(super) order: VecDeque<String>,
    pub(super) bytes: usize,
}

impl TileCache {
    pub(super) fn get(&self, key: &str) -> Option<Arc<Vec<u8>>> {
        self.tiles.get(key).cloned()
    }

    pub(super) fn insert(&mut self, key: String, png: Arc<Vec<u8>>) {
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
pub(super) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// What a render polls: its client left, or its page moved to a newer generation.
pub(super) struct Watch<'a> {
    pub(super) shared: &'a Shared,
    pub(super) job: &'a Job,
}

impl ifslab::progress::Progress for Watch<'_> {
    fn cancelled(&self) -> bool {
        self.job.cancel.load(Ordering::SeqCst)
            || self.shared.newer(self.job.tile.generation).is_some()
    }
}

pub(super) fn stale(job: &Job, latest: u64) -> Response {
    let (sid, generation) = job.tile.generation.unwrap_or_default();
    Response::text(
        409,
        &format!(
            "stale: generation {generation} of page {sid} is older than {latest}, the latest it \
             asked for; not drawn"
        ),
    )
}

/// A worker: draws queued tiles until the queue closes.
pub(super) fn work(shared: &Shared) {
    loop {
        let job = {
            let mut q = lock(&shared.queue);
            loop {
                if let Some(j) = q.jobs.pop_front() {
                    break j;
                }
                if q.closed {
                    return;
                }
                q = shared.ready.wait(q).unwrap_or_else(|e| e.into_inner());
            }
        };
        if job.cancel.load(Ordering::SeqCst) {
            bump(&shared.stats.cancelled_queued);
            continue;
        }
        if let Some(latest) = shared.newer(job.tile.generation) {
            bump(&shared.stats.stale);
            let _ = job.reply.send(stale(&job, latest));
            continue;
        }
        let key = format!("{}/{}", job.view, job.tile.key());
        if let Some(bytes) = lock(&shared.cache).get(&key) {
            let _ = job.reply.send(png(bytes.to_vec()));
            continue;
        }
        let View::Tiles { renderer, .. } = &shared.site.views[job.view] else {
            let _ = job.reply.send(Response::text(500, "not a tiled view"));
            continue;
        };
        let watch = Watch { shared, job: &job };
        // A panic in a render costs its tile, not the worker.
        let drawn = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            renderer.render_png(&job.tile, &watch)
        }));
        let answer = match drawn {
            Ok(Ok(bytes)) => {
                bump(&shared.stats.drawn);
                let bytes = Arc::new(bytes);
                lock(&shared.cache).insert(key, bytes.clone());
                png(bytes.to_vec())
            }
            Ok(Err(e)) if e.is_cancelled() => match shared.newer(job.tile.generation) {
                Some(latest) => {
                    bump(&shared.stats.stale);
                    stale(&job, latest)
                }
                None => {
                    bump(&shared.stats.cancelled_drawing);
                    continue;
                }
            },
            Ok(Err(e)) => Response::text(500, &format!("the tile was not drawn: {e:#}")),
            Err(_) => Response::text(500, "the tile's render panicked"),
        };
        // A client that left is no error of the server's.
        let _ = job.reply.send(answer);
    }
}
