// Fixtures shared by the instruction-count workloads: `benches/workload.rs` (the renderers
// called directly) and `strategies/benches/problem_workload.rs` (the same settings through
// the problems), so that the two measure the same scenes. Included with `include!`; paths
// are written out so the including file needs no imports for them.

/// The SDF iteration's scene (`benches/sdf.rs`): a Koch curve of depth 3 at 256², σ 1.5,
/// cut-off 6σ; the target drawn from the truth, and the slightly moved pattern to fit.
struct KochSdfFixture {
    side: usize,
    sigma: f64,
    view: ifslab::render::sdf::SdfView,
    cfg: ifslab::render::sdf::SdfRenderConfig,
    current: ifslab::model::segment::Pattern,
    target: Vec<f64>,
}

fn koch_sdf_fixture() -> KochSdfFixture {
    use ifslab::model::segment::{SegmentMap, builtin};
    use ifslab::render::sdf::{SdfRaster, SdfRenderConfig, SdfView};
    const SIDE: usize = 256;
    const SIGMA: f64 = 1.5;
    let koch_at = |to: [[f64; 2]; 2]| {
        let m = SegmentMap::between([0.0, 0.0], [1.0, 0.0], to[0], to[1]).expect("a map");
        builtin("koch")
            .expect("koch")
            .transformed(&m)
            .expect("a pattern")
    };
    let view = SdfView::unit_square(SIDE);
    let truth = koch_at([[0.15, 0.4], [0.85, 0.4]]);
    let current = koch_at([[0.16, 0.41], [0.84, 0.38]]);
    let cfg = SdfRenderConfig {
        depth: 3,
        cutoff: Some(6.0 * SIGMA),
    };
    let target = SdfRaster::render(&truth, &view, &cfg)
        .expect("render")
        .image(SIGMA);
    KochSdfFixture {
        side: SIDE,
        sigma: SIGMA,
        view,
        cfg,
        current,
        target,
    }
}

/// One learnable-flame layer of 8 generators (spherical, handkerchief, swirl, polar, disc,
/// sinusoidal, linear + exponential, linear) over white at 100², 200 × 200 samples, and a
/// fixed pseudo-random RGB target.
fn learnable_flame_fixture() -> (
    ifslab::model::flame::learnable::FlameStack,
    ifslab::render::flame_diff::DiffFlameConfig,
    Vec<f32>,
) {
    use ifslab::model::flame::VariationKind as V;
    use ifslab::model::flame::learnable::{
        Background, FlameStack, Learn, LearnableFlame, LearnableInit,
    };
    use ifslab::render::flame_diff::DiffFlameConfig;
    let vars = [
        vec![V::Spherical],
        vec![V::Handkerchief],
        vec![V::Swirl],
        vec![V::Polar],
        vec![V::Disc],
        vec![V::Sinusoidal],
        vec![V::Linear, V::Exponential],
        vec![V::Linear],
    ];
    let layer = LearnableFlame::random(&vars, Learn::default(), &LearnableInit::default(), 7)
        .expect("a random flame");
    let st = FlameStack {
        layers: vec![layer],
        background: Background::Fixed([1.0; 3]),
    };
    let cfg = DiffFlameConfig {
        trajectories: 200,
        steps: 200,
        ..DiffFlameConfig::default()
    };
    let target: Vec<f32> = (0..3 * cfg.size * cfg.size)
        .map(|i| ((i * 7919) % 101) as f32 / 100.0)
        .collect();
    (st, cfg, target)
}
