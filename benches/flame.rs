//! Flame render throughput against flam3-render, in the same run, on the same `.flame` files.
//!
//! Two flam3-genome random flames from the image fixtures, reframed to 1024² at quality 20
//! (21 M samples each, flam3's density estimation and filter as the files say):
//! - `v00`: four linear transforms, where the renderer's own machinery (transform choice,
//!   colour, camera, histogram) is all the work;
//! - `m05`: flam3-genome's default variation mix (polar, eyefish, fisheye, disc2, waves2),
//!   what a typical random flame costs.
//!
//! Each is rendered by [`render_flame`] on 2 and 1 threads and by `flam3-render` with
//! `nthreads=2` and `nthreads=1`, both writing their 8-bit PNG. Throughput is samples per
//! second of the whole render (histogram, density estimation, filter, tone map and PNG
//! included on both sides). The flam3 variants need `flam3-render` (Debian flam3-utils)
//! and are left out with a message without it. Before timing, the SSIM of our image
//! against flam3's is printed beside flam3's against itself (another seed; at quality 20
//! the sampling noise alone keeps both well below 1), so the speed is that of a matching
//! picture.

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::process::Command;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use ifslab::metrics::ssim;
use ifslab::model::flame::{Flame, read_flames, write_flames};
use ifslab::render::flame::{Depth, FlameRenderConfig, render_flame};
use ifslab::render::image_io::load_grey;

const SIZE: u32 = 1024;
const QUALITY: f64 = 20.0;

fn flame(name: &str) -> Flame {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/flame/images")
        .join(format!("{name}.flame"));
    let mut f = read_flames(&path).unwrap().remove(0);
    f.scale *= SIZE as f64 / f.size[1] as f64;
    f.size = [SIZE, SIZE];
    f.quality = QUALITY;
    f
}

fn flam3_available() -> bool {
    Command::new("flam3-render")
        .env("in", "/nonexistent")
        .output()
        .is_ok()
}

fn flam3_render(file: &Path, out: &Path, threads: usize) {
    flam3_seeded(file, out, threads, 1)
}

fn flam3_seeded(file: &Path, out: &Path, threads: usize, seed: u64) {
    let st = Command::new("flam3-render")
        .env("in", file)
        .env("out", out)
        .env("nthreads", threads.to_string())
        .env("verbose", "0")
        .env("isaac_seed", seed.to_string())
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "flam3-render failed: {}",
        String::from_utf8_lossy(&st.stderr)
    );
}

fn ours(f: &Flame, threads: usize, out: &Path) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let cfg = FlameRenderConfig {
        seed: 1,
        ..FlameRenderConfig::default()
    };
    let img = pool.install(|| render_flame(f, &cfg, None)).unwrap();
    img.save_png(out, Depth::Eight, false).unwrap();
    black_box(img.stats.hits);
}

fn bench_flames(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let has_flam3 = flam3_available();
    if !has_flam3 {
        eprintln!("flam3-render not found (apt-get install flam3-utils): timing ours only");
    }
    for name in ["v00", "m05"] {
        let f = flame(name);
        let file: PathBuf = dir.path().join(format!("{name}.flame"));
        write_flames(&file, std::slice::from_ref(&f)).unwrap();
        let (ours_png, theirs_png) = (dir.path().join("ours.png"), dir.path().join("f3.png"));
        if has_flam3 {
            ours(&f, 2, &ours_png);
            flam3_render(&file, &theirs_png, 1);
            let again_png = dir.path().join("f3b.png");
            flam3_seeded(&file, &again_png, 1, 2);
            let [a, b, c] = [&ours_png, &theirs_png, &again_png].map(|p| load_grey(p).unwrap());
            let n = SIZE as usize;
            let s = ssim(&a.values, &b.values, n, n).unwrap();
            let s_self = ssim(&c.values, &b.values, n, n).unwrap();
            eprintln!(
                "{name}: SSIM of our render against flam3-render's {s:.3}, \
                 of flam3's against itself (another seed) {s_self:.3}"
            );
        }
        let samples = (QUALITY * SIZE as f64 * SIZE as f64) as u64;
        let mut g = c.benchmark_group(format!("flame_{name}_1024px_q20"));
        g.sample_size(10);
        g.throughput(Throughput::Elements(samples));
        for threads in [2, 1] {
            g.bench_function(format!("ours_{threads}t"), |b| {
                b.iter(|| ours(&f, threads, &ours_png))
            });
        }
        if has_flam3 {
            for threads in [2, 1] {
                g.bench_function(format!("flam3_{threads}t"), |b| {
                    b.iter(|| flam3_render(&file, &theirs_png, threads))
                });
            }
        }
        g.finish();
    }
}

criterion_group!(benches, bench_flames);
criterion_main!(benches);
