//! `ifslab serve CODE_OR_RUN`: a local web page that pans and zooms deep into an attractor.

use ifslab_experiments::serve::{ServeOptions, Site, TileOptions, serve};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A code file (JSON), a built-in code's name, a finished run folder (its target and
    /// recovered code side by side, and its loss curve), or a `.flame` file (its flames
    /// laid over one another, in the flame renderer's tiles) or a folder with
    /// `learned.flame`.
    pub source: String,
    /// Port to listen on (0: any free port).
    #[arg(long, default_value_t = 8080)]
    pub port: u16,
    /// Address to listen on; the default serves this machine only.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// Chaos-game points per tile (at most 1e8): 1M, 5e6… [default: 1M for a code, 4M
    /// samples for a flame, whose tiles go 2^L deep at 1 sample per pixel while 4^L·65536
    /// samples or fewer suffice]
    #[arg(long, value_parser = ifslab::budget::parse_count)]
    pub points: Option<u64>,
    /// Threads drawing tiles [default: the CPUs, 2 to 8].
    #[arg(long)]
    pub workers: Option<usize>,
    /// Seed of every tile's chaos game.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let mut tiles = TileOptions {
        seed: a.seed,
        ..TileOptions::default()
    };
    if let Some(n) = a.points {
        tiles.points = n;
        tiles.flame_samples = n;
    }
    let site = Site::load(&a.source, tiles)?;
    let max_level = site.tiling.max_level();
    let site_note = site.note.clone();
    let mut opts = ServeOptions {
        host: a.host,
        port: a.port,
        ..ServeOptions::default()
    };
    if let Some(w) = a.workers {
        opts.workers = w;
    }
    let server = serve(site, &opts)?;
    if !server.addr().ip().is_loopback() {
        eprintln!(
            "warning: listening on {}, reachable from other machines (--host 127.0.0.1 keeps it to this one)",
            server.addr()
        );
    }
    eprintln!(
        "serving {} at {} (tiles to level {max_level}, zoom 2^{max_level}; Ctrl-C stops)",
        a.source,
        server.url()
    );
    if let Some(note) = &site_note {
        eprintln!("{note}");
    }
    server.wait();
    Ok(())
}
