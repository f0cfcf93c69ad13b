//! One iteration of a segment-pattern fit at the peer's setting: the Koch pattern (5 control
//! points, 4 maps) rendered by the SDF raster at 256², the multi-scale MSE on pixels against a
//! target and its gradient, back through the raster to the control points — the work of
//! `SdfProblem::evaluate`. Depth 3 (64 primitives, the peer's PyTorch code: 1.72 s per
//! iteration) and depth 6 (4096 primitives); both with the pixel loss's 6σ cut-off and with
//! the exact distance at every pixel (what the distance loss needs).
//!
//! Run with `cargo bench --bench sdf`; sized for a 2-core machine.

/// The allocator the `ifslab` binary ships with, so the figures are what users get.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use ifslab::loss::{ImageLoss, MsMse};
use ifslab::model::segment::{Pattern, SegmentMap, builtin};
use ifslab::render::sdf::{SdfRaster, SdfRenderConfig, SdfView};

const SIDE: usize = 256;
const SIGMA: f64 = 1.5;

fn koch_at(to: [[f64; 2]; 2]) -> Pattern {
    let m = SegmentMap::between([0.0, 0.0], [1.0, 0.0], to[0], to[1]).unwrap();
    builtin("koch").unwrap().transformed(&m).unwrap()
}

/// Loss and gradient with respect to the control points, as the fit computes them.
fn iteration(p: &Pattern, target: &[f64], view: &SdfView, cfg: &SdfRenderConfig) -> Vec<f64> {
    let r = SdfRaster::render(p, view, cfg).unwrap();
    let img = r.image(SIGMA);
    let (_, g) = MsMse::new(4)
        .value_and_grad::<f64>(&img, target, SIDE, SIDE)
        .unwrap();
    let gd = r.image_backward(SIGMA, &g);
    r.backward(p, &gd).unwrap()
}

fn sdf_iteration(c: &mut Criterion) {
    let view = SdfView::unit_square(SIDE);
    let truth = koch_at([[0.15, 0.4], [0.85, 0.4]]);
    // The fit's state: the curve slightly off the target.
    let current = koch_at([[0.16, 0.41], [0.84, 0.38]]);
    let mut g = c.benchmark_group("sdf_koch_256");
    g.sample_size(20).measurement_time(Duration::from_secs(8));
    for depth in [3usize, 6] {
        for (label, cutoff) in [("cutoff", Some(6.0 * SIGMA)), ("exact", None)] {
            let cfg = SdfRenderConfig { depth, cutoff };
            let target = SdfRaster::render(&truth, &view, &cfg).unwrap().image(SIGMA);
            g.bench_function(format!("depth{depth}_{label}_forward_backward"), |b| {
                b.iter(|| iteration(black_box(&current), &target, &view, &cfg))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, sdf_iteration);
criterion_main!(benches);
