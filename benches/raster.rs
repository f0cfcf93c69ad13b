//! Evaluation-render throughput: a 10-map random code, 50M points into 1024² with 16×
//! binary supersampling (the chaotic-splatting paper's ground-truth setting).
//!
//! Measurements in the same run (group `eval_render_10maps_1024px_16x`, wall-clock time):
//! - `render`: the streaming renderer as shipped (chaos game compiled for FMA where the CPU
//!   has it, points binned by tile);
//! - `chaos_only`: the same trajectories through the same `PointStream` (same instruction
//!   set, same four-lane loop, same warm-up, same schedule), each point only folded into a
//!   checksum: the floor;
//! - `render_portable` / `chaos_only_portable`: both again with the chaos game compiled for
//!   baseline x86-64, where every `mul_add` is a call (what the FMA dispatch buys);
//! - `baseline_direct_write`: the renderer as it was before tile binning, and the best simple
//!   alternative: the same stream and schedule, each point's bit set directly in its
//!   worker's 32 MiB row-major bitset, the bitsets OR-merged and popcount-downsampled;
//! - `baseline_store_then_raster_5M`: the textbook pipeline — store every point (same
//!   stream), then draw them into a byte-per-sub-pixel 16384² buffer and box-downsample — at
//!   1/10 of the points (its buffer alone is 256 MiB), reported per point; serial drawing,
//!   kept for continuity with earlier figures, not as the yardstick.
//!
//! Group `eval_render_cpu_time` measures `render` and `chaos_only` again in process CPU time
//! (user + system, all threads; Linux only). On a machine shared with other jobs the
//! scheduler hands a short job and a long one different shares of the cores, which moves
//! wall-clock ratios; CPU time is what each costs whatever else runs.
//!
//! Group `deep_zoom_sierpinski_256px_5M`: the Sierpiński triangle's full view beside zooms of
//! 2¹⁰ and 2²⁰ drawn through the code's words (`RenderConfig::deep_zoom`), 5 M points each:
//! a deep zoom costs what the full view costs.

/// The allocator the `ifslab` binary ships with, so the figures are what users get.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::hint::black_box;
use std::sync::Mutex;

use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use ifslab::chaos::{Isa, LANES, MapSampler, PointSink, PointStream};
use ifslab::model::random::sample_code;
use ifslab::model::{Affine2, IfsCode, Window};
use ifslab::render::{RenderConfig, View, render, render_with_isa};
use rayon::prelude::*;

const POINTS: u64 = 50_000_000;

/// The renderer's trajectory layout: 1024 per round, 100 warm-up steps, starts in [−1, 1]².
const TRAJECTORIES: usize = 1024;

/// Folds every point into one word, so nothing is optimised away and nothing is stored.
struct Checksum(u64);

impl PointSink for Checksum {
    #[inline(always)]
    fn put(&mut self, p: [f64; 2]) {
        self.0 ^= p[0].to_bits() ^ p[1].to_bits();
    }
}

/// Keeps every point.
struct Store(Vec<[f64; 2]>);

impl PointSink for Store {
    #[inline(always)]
    fn put(&mut self, p: [f64; 2]) {
        self.0.push(p);
    }
}

/// Sets each in-window point's bit in a row-major `side`² bitset: the direct write.
struct DirectBits<'a> {
    bits: &'a mut [u64],
    x0: f64,
    y1: f64,
    kx: f64,
    ky: f64,
    side: f64,
    row_words: usize,
}

impl PointSink for DirectBits<'_> {
    #[inline(always)]
    fn put(&mut self, p: [f64; 2]) {
        let fx = (p[0] - self.x0) * self.kx;
        let fy = (self.y1 - p[1]) * self.ky;
        if (fx >= 0.0) & (fx < self.side) & (fy >= 0.0) & (fy < self.side) {
            let (x, y) = (fx as usize, fy as usize);
            self.bits[y * self.row_words + (x >> 6)] |= 1u64 << (x & 63);
        }
    }
}

struct Setup {
    maps: Vec<Affine2>,
    probs: Vec<f64>,
    sampler: MapSampler,
    cfg: RenderConfig,
    window: Window,
}

impl Setup {
    fn new() -> Setup {
        let s = sample_code(10, 3).unwrap();
        let probs = IfsCode::from_affine2(None, &s.maps)
            .unwrap()
            .evaluation_probabilities()
            .unwrap();
        let cfg = RenderConfig {
            width: 1024,
            height: 1024,
            points: POINTS,
            supersample: 16,
            seed: 1,
            ..RenderConfig::default()
        };
        // Fix the window once so every variant measures drawing, not the pilot run.
        let pilot = RenderConfig {
            points: 10_000,
            ..cfg.clone()
        };
        let window = render(&s.maps, &probs, &pilot, None).unwrap().stats.window;
        Setup {
            sampler: MapSampler::new(&probs).unwrap(),
            maps: s.maps,
            probs,
            cfg: RenderConfig {
                view: View::Window(window),
                ..cfg
            },
            window,
        }
    }

    fn draw(&self, isa: Isa) -> usize {
        render_with_isa(&self.maps, &self.probs, &self.cfg, None, isa)
            .unwrap()
            .values
            .len()
    }

    /// The trajectories of a `points`-point render, each batch of four into its own sink,
    /// batches taken by whichever thread is free (the renderer's schedule).
    fn stream<S: PointSink + Send>(
        &self,
        isa: Isa,
        points: u64,
        sink: impl Fn() -> S + Sync + Send,
    ) -> Vec<S> {
        let stream = PointStream::new(&self.maps, &self.sampler, self.cfg.seed, 1.0, 100)
            .unwrap()
            .with_isa(isa)
            .unwrap();
        let t = TRAJECTORIES;
        let points_of = |i: usize| points / t as u64 + u64::from((i as u64) < points % t as u64);
        (0..t.div_ceil(LANES))
            .into_par_iter()
            .map(|b| {
                let (lo, hi) = (b * LANES, ((b + 1) * LANES).min(t));
                let ns: Vec<u64> = (lo..hi).map(points_of).collect();
                let mut s = sink();
                stream.run(lo as u64, &ns, &mut s).unwrap();
                s
            })
            .collect()
    }

    fn chaos_only(&self, isa: Isa) -> u64 {
        self.stream(isa, POINTS, || Checksum(0))
            .iter()
            .fold(0, |a, s| a ^ s.0)
    }

    /// The pre-binning renderer: one 16384² bitset per worker thread, bits set where the
    /// points land, merged by OR, box-downsampled by popcount (16 sub-pixels are 16 bits).
    fn direct_write(&self, isa: Isa) -> usize {
        let (w, s) = (1024usize, 16usize);
        let big = w * s;
        let row_words = big / 64;
        let threads = rayon::current_num_threads().max(1);
        let bufs: Vec<Mutex<Vec<u64>>> = (0..threads)
            .map(|_| Mutex::new(vec![0u64; row_words * big]))
            .collect();
        let stream = PointStream::new(&self.maps, &self.sampler, self.cfg.seed, 1.0, 100)
            .unwrap()
            .with_isa(isa)
            .unwrap();
        let (win, size) = (&self.window, self.window.size());
        let t = TRAJECTORIES;
        let points_of = |i: usize| POINTS / t as u64 + u64::from((i as u64) < POINTS % t as u64);
        (0..t.div_ceil(LANES)).into_par_iter().for_each(|b| {
            let (lo, hi) = (b * LANES, ((b + 1) * LANES).min(t));
            let ns: Vec<u64> = (lo..hi).map(points_of).collect();
            let slot = rayon::current_thread_index().unwrap_or(0) % threads;
            let mut buf = bufs[slot].lock().unwrap();
            let mut sink = DirectBits {
                bits: &mut buf,
                x0: win.min[0],
                y1: win.max[1],
                kx: big as f64 / size[0],
                ky: big as f64 / size[1],
                side: big as f64,
                row_words,
            };
            stream.run(lo as u64, &ns, &mut sink).unwrap();
        });
        let mut bufs: Vec<Vec<u64>> = bufs.into_iter().map(|m| m.into_inner().unwrap()).collect();
        let mut acc = bufs.remove(0);
        for other in bufs {
            acc.par_chunks_mut(1 << 14)
                .zip(other.par_chunks(1 << 14))
                .for_each(|(a, b)| a.iter_mut().zip(b).for_each(|(x, y)| *x |= y));
        }
        let mut out = vec![0.0f32; w * w];
        out.par_chunks_mut(w).enumerate().for_each(|(py, out_row)| {
            let mut counts = vec![0u32; w];
            for sy in 0..s {
                let row = &acc[(py * s + sy) * row_words..][..row_words];
                for (j, &word) in row.iter().enumerate() {
                    for q in 0..4 {
                        counts[j * 4 + q] += ((word >> (q * 16)) & 0xFFFF).count_ones();
                    }
                }
            }
            for (o, c) in out_row.iter_mut().zip(counts) {
                *o = c as f32 / 256.0;
            }
        });
        out.len()
    }

    /// Store every point, then draw bytes into a 16384² buffer and box-downsample.
    fn store_then_raster(&self, points: u64) -> usize {
        let pts = self.stream(Isa::detect(), points, || Store(Vec::new()));
        let (w, s) = (1024usize, 16usize);
        let big = w * s;
        let mut buf = vec![0u8; big * big];
        let (win, size) = (&self.window, self.window.size());
        for p in pts.iter().flat_map(|s| &s.0) {
            let fx = (p[0] - win.min[0]) / size[0] * big as f64;
            let fy = (win.max[1] - p[1]) / size[1] * big as f64;
            if fx >= 0.0 && fy >= 0.0 && fx < big as f64 && fy < big as f64 {
                buf[fy as usize * big + fx as usize] = 1;
            }
        }
        let out: Vec<f32> = (0..w * w)
            .into_par_iter()
            .map(|i| {
                let (py, px) = (i / w, i % w);
                let mut n = 0u32;
                for sy in 0..s {
                    let row = &buf[(py * s + sy) * big + px * s..][..s];
                    n += row.iter().map(|&v| v as u32).sum::<u32>();
                }
                n as f32 / (s * s) as f32
            })
            .collect();
        out.len()
    }
}

fn bench_render(c: &mut Criterion) {
    let st = Setup::new();
    let mut g = c.benchmark_group("eval_render_10maps_1024px_16x");
    g.sample_size(10);
    g.throughput(Throughput::Elements(POINTS));
    let isa = Isa::detect();
    g.bench_function("render", |b| b.iter(|| black_box(st.draw(isa))));
    g.bench_function("chaos_only", |b| b.iter(|| black_box(st.chaos_only(isa))));
    if isa != Isa::Portable {
        g.bench_function("render_portable", |b| {
            b.iter(|| black_box(st.draw(Isa::Portable)))
        });
        g.bench_function("chaos_only_portable", |b| {
            b.iter(|| black_box(st.chaos_only(Isa::Portable)))
        });
    }
    g.bench_function("baseline_direct_write", |b| {
        b.iter(|| black_box(st.direct_write(isa)))
    });
    let n_base = POINTS / 10;
    g.throughput(Throughput::Elements(n_base));
    g.bench_function("baseline_store_then_raster_5M", |b| {
        b.iter(|| black_box(st.store_then_raster(n_base)))
    });
    g.finish();
}

/// A deep zoom costs what the full view costs: the Sierpiński triangle at 256², 5 M points,
/// the full view beside zooms of 2¹⁰ and 2²⁰ on the middle of its base, drawn through the
/// code's words (`RenderConfig::deep_zoom`; the plain game lands no point at 2²⁰).
fn bench_deep_zoom(c: &mut Criterion) {
    let code = ifslab::model::library::builtin("sierpinski").unwrap();
    let maps = code.affine2().unwrap();
    let probs = code.evaluation_probabilities().unwrap();
    let cfg = RenderConfig {
        width: 256,
        height: 256,
        points: 5_000_000,
        seed: 1,
        deep_zoom: true,
        ..RenderConfig::default()
    };
    let mut g = c.benchmark_group("deep_zoom_sierpinski_256px_5M");
    g.sample_size(10);
    g.throughput(Throughput::Elements(cfg.points));
    for (name, zoom) in [
        ("full_view", None),
        ("words_2e10", Some(10)),
        ("words_2e20", Some(20)),
    ] {
        let cfg = RenderConfig {
            zoom: zoom.map(|k| ifslab::render::Zoom {
                factor: f64::powi(2.0, k),
                center: Some([0.5, 0.0]),
            }),
            ..cfg.clone()
        };
        g.bench_function(name, |b| {
            b.iter(|| {
                black_box(
                    render(&maps, &probs, &cfg, None)
                        .unwrap()
                        .stats
                        .points_in_window,
                )
            })
        });
    }
    g.finish();
}

fn bench_render_cpu(c: &mut Criterion<CpuTime>) {
    if cpu_ns().is_none() {
        eprintln!("eval_render_cpu_time: no /proc/self/stat here, skipped");
        return;
    }
    let st = Setup::new();
    let mut g = c.benchmark_group("eval_render_cpu_time");
    g.sample_size(10);
    g.throughput(Throughput::Elements(POINTS));
    let isa = Isa::detect();
    g.bench_function("render", |b| b.iter(|| black_box(st.draw(isa))));
    g.bench_function("chaos_only", |b| b.iter(|| black_box(st.chaos_only(isa))));
    g.bench_function("baseline_direct_write", |b| {
        b.iter(|| black_box(st.direct_write(isa)))
    });
    g.finish();
}

/// Process CPU time (user + system, every thread) in nanoseconds, from Linux's
/// `/proc/self/stat` (10 ms ticks: USER_HZ is 100).
struct CpuTime;

fn cpu_ns() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // After the parenthesised command name: field 3 (state) is index 0, utime (14) index
    // 11, stime (15) index 12.
    let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    let ticks = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks * 1e7)
}

impl Measurement for CpuTime {
    type Intermediate = f64;
    type Value = f64;

    fn start(&self) -> f64 {
        cpu_ns().unwrap_or(0.0)
    }

    fn end(&self, start: f64) -> f64 {
        cpu_ns().unwrap_or(0.0) - start
    }

    fn add(&self, a: &f64, b: &f64) -> f64 {
        a + b
    }

    fn zero(&self) -> f64 {
        0.0
    }

    fn to_f64(&self, v: &f64) -> f64 {
        *v
    }

    fn formatter(&self) -> &dyn ValueFormatter {
        &CpuFormatter
    }
}

struct CpuFormatter;

impl ValueFormatter for CpuFormatter {
    fn scale_values(&self, typical: f64, values: &mut [f64]) -> &'static str {
        let (k, unit) = if typical >= 1e9 {
            (1e-9, "s cpu")
        } else {
            (1e-6, "ms cpu")
        };
        values.iter_mut().for_each(|v| *v *= k);
        unit
    }

    fn scale_throughputs(
        &self,
        _typical: f64,
        throughput: &Throughput,
        values: &mut [f64],
    ) -> &'static str {
        let n = match throughput {
            Throughput::Elements(n) | Throughput::Bytes(n) | Throughput::BytesDecimal(n) => {
                *n as f64
            }
        };
        values.iter_mut().for_each(|v| *v = n / (*v * 1e-9) / 1e6);
        "M/cpu-s"
    }

    fn scale_for_machines(&self, _values: &mut [f64]) -> &'static str {
        "ns cpu"
    }
}

criterion_group!(benches, bench_render, bench_deep_zoom);
criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(CpuTime);
    targets = bench_render_cpu
}
criterion_main!(benches, cpu);
