//! A fixed workload for comparing two builds of the texture encoder by instruction count
//! (wall-clock on a shared machine cannot resolve a few per cent): `encode` on the 512²
//! brick texture (`data/textures/brick.png`, grey) with a ±32-texel search window, run a
//! given number of times.
//!
//! ```sh
//! cargo bench -p ifslab-strategies --bench encode_workload --no-run   # prints the path
//! RAYON_NUM_THREADS=1 valgrind --tool=cachegrind --cache-sim=no \
//!     target/release/deps/encode_workload-<hash> 2
//! ```
//!
//! The per-call cost is the difference between runs with N and N + k calls, divided by k
//! (BENCHMARKS.md §4).

use std::hint::black_box;
use std::path::Path;

use ifslab_strategies::problems::fractal_coding::{EncoderConfig, Texture, encode};

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    // `cargo bench` passes `--bench`; everything else is ours.
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let calls = match args.as_slice() {
        [n] => n.parse::<usize>().unwrap_or_else(|_| {
            eprintln!("usage: encode_workload <calls>");
            std::process::exit(2)
        }),
        _ => 0,
    };
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/textures/brick.png");
    let tex = Texture::load(&path, false).expect("data/textures/brick.png");
    let cfg = EncoderConfig {
        window: 32,
        ..EncoderConfig::default()
    };
    let start = std::time::Instant::now();
    let mut sink = 0usize;
    for _ in 0..calls {
        let code = encode(&tex, &cfg).expect("encode");
        sink += black_box(&code).code.coords().len();
    }
    eprintln!(
        "encode × {calls}: {:.1} ms per call (wall) [{}]",
        start.elapsed().as_secs_f64() * 1e3 / calls.max(1) as f64,
        black_box(sink)
    );
}
