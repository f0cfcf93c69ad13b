//! Fractal-coding texture upsampling: encoding time for a 512² texture (the paper's ±255
//! window) and 8× upsampling throughput (output texels per second) against bilinear
//! upsampling to the same 4096² size, in the same run.
//!
//! Goal (BENCHMARKS.md): decoding within 3× of bilinear's time. The like-for-like pair is
//! `fractal_decode` against `bilinear_parallel`: both per texel, rayon over rows, into a
//! reused output buffer. `bilinear_image_crate`
//! (single-threaded, allocating) is there for reference.

/// The allocator the `ifslab` binary ships with, so the figures are what users get.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::path::Path;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use ifslab_strategies::problems::fractal_coding::{
    EncoderConfig, Filter, Texture, bilinear_into, decode_into, encode, output_size, upsample,
};

fn brick() -> Texture {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/textures/brick.png");
    Texture::load(&path, false).expect("data/textures/brick.png")
}

fn bench_encode(c: &mut Criterion) {
    let tex = brick();
    let mut g = c.benchmark_group("fractal_coding/encode_512");
    g.sample_size(10);
    g.measurement_time(std::time::Duration::from_secs(30));
    for window in [255u32, 32] {
        let cfg = EncoderConfig {
            window,
            ..EncoderConfig::default()
        };
        g.bench_function(format!("window_{window}"), |b| {
            b.iter(|| encode(&tex, &cfg).expect("encode"))
        });
    }
    g.finish();
}

/// An RGB 512² texture for throughput: brick, grass and gravel as the three channels.
fn rgb() -> Texture {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/textures");
    let ch: Vec<Texture> = ["brick", "grass", "gravel"]
        .iter()
        .map(|n| Texture::load(&dir.join(format!("{n}.png")), true).expect("texture"))
        .collect();
    Texture::from_fn(512, 512, 3, |x, y, k| ch[k].get(x, y, 0)).expect("rgb")
}

fn bench_upsample(c: &mut Criterion) {
    for (name, tex) in [("grey", brick()), ("rgb", rgb())] {
        let code = encode(&tex, &EncoderConfig::default())
            .expect("encode")
            .code;
        let factor = 8;
        let (_, w, h) = output_size(&code, factor).expect("size");
        let mut out = vec![0.0f32; w * h * tex.channels()];
        let mut g = c.benchmark_group(format!("fractal_coding/upsample_8x_512_{name}"));
        g.throughput(Throughput::Elements((w * h) as u64));
        g.sample_size(20);
        g.bench_function("fractal_decode", |b| {
            b.iter(|| decode_into(&code, factor, &mut out).expect("decode"))
        });
        g.bench_function("bilinear_parallel", |b| {
            b.iter(|| bilinear_into(&tex, factor, &mut out).expect("bilinear"))
        });
        g.sample_size(10);
        g.measurement_time(std::time::Duration::from_secs(15));
        g.bench_function("bilinear_image_crate", |b| {
            b.iter(|| upsample(&tex, factor, Filter::Bilinear).expect("bilinear"))
        });
        g.finish();
    }
}

criterion_group!(benches, bench_upsample, bench_encode);
criterion_main!(benches);
