//! Decoding timings: 8× fractal decoding against bilinear upsampling to the same size, per
//! frame, on all threads and on one (medians of repeats).

use std::time::Instant;

use ifslab_strategies::problems::fractal_coding::{
    Filter, FractalCode, Texture, bilinear_into, decode_into, output_size, upsample,
};

use super::TimingRow;

/// Median seconds of `reps` runs of `f`.
pub(super) fn median_secs(
    reps: usize,
    mut f: impl FnMut() -> crate::Result<()>,
) -> crate::Result<f64> {
    f()?; // warm-up (caches, page faults of the output buffer)
    let mut t = Vec::with_capacity(reps);
    for _ in 0..reps.max(1) {
        let t0 = Instant::now();
        f()?;
        t.push(t0.elapsed().as_secs_f64());
    }
    t.sort_by(f64::total_cmp);
    Ok(t[t.len() / 2])
}

pub(super) fn timing(
    name: &str,
    src: &Texture,
    code: &FractalCode,
    reps: usize,
) -> crate::Result<Vec<TimingRow>> {
    let factor = 8;
    let (_, w, h) = output_size(code, factor)?;
    let mut rows = Vec::new();
    let all = rayon::current_num_threads();
    for threads in [all, 1] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()?;
        let (ours, bil) = pool.install(|| -> crate::Result<(f64, f64)> {
            let mut buf = vec![0.0f32; w * h * src.channels()];
            let ours = median_secs(reps, || Ok(decode_into(code, factor, &mut buf)?))?;
            let bil = median_secs(reps, || Ok(bilinear_into(src, factor, &mut buf)?))?;
            Ok((ours, bil))
        })?;
        let lib = if threads == 1 {
            Some(median_secs(reps.min(3), || {
                upsample(src, factor, Filter::Bilinear)?;
                Ok(())
            })?)
        } else {
            None
        };
        let texels = (w * h) as f64;
        rows.push(TimingRow {
            texture: name.into(),
            threads,
            output: format!("{w}×{h}×{}", src.channels()),
            fractal_ms: ours * 1e3,
            bilinear_ms: bil * 1e3,
            ratio: ours / bil,
            fractal_mtexels_s: texels / ours / 1e6,
            bilinear_mtexels_s: texels / bil / 1e6,
            image_crate_bilinear_ms: lib.map(|s| s * 1e3),
        });
    }
    Ok(rows)
}
