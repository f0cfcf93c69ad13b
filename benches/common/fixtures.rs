// Scenes shared by the instruction-count workloads — `benches/workload.rs` (the renderers
// called directly), `strategies/benches/{problem,model}_workload.rs` (the same settings
// through the problems) — and `strategies/tests/sampling_bits.rs`, so that they measure
// and pin the same scenes. Included with `include!`; paths are written out so the including
// file needs no imports for them.

/// `(stage, calls)` from a workload's command line (`cargo bench` passes `--bench`, which
/// is skipped); no arguments, as under `cargo bench`, is one cheap `setup` pass.
#[allow(dead_code)]
fn stage_and_calls(usage: &str) -> (String, usize) {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    match args.as_slice() {
        [s, n] => (
            s.clone(),
            n.parse::<usize>().expect("calls: a whole number"),
        ),
        [] => ("setup".to_string(), 0),
        _ => panic!("usage: {usage}"),
    }
}

/// `ifslab demo`'s splat (BENCHMARKS.md §2, "demo setting"): 96², 4× supersampling, σ 1,
/// 1000 × 110 points.
#[allow(dead_code)]
fn demo_splat_config() -> ifslab::render::splat::SplatConfig {
    ifslab::render::splat::SplatConfig {
        width: 96,
        height: 96,
        supersample: 4,
        sigma: 1.0,
        blend: ifslab::render::splat::Blend::Coverage,
        game: ifslab::chaos::ChaosGame {
            trajectories: 1000,
            length: 110,
            ..ifslab::chaos::ChaosGame::default()
        },
        ..ifslab::render::splat::SplatConfig::default()
    }
}

/// A random code of `n` maps (seed 3) and, as SVD θ, the same code with its offsets shrunk
/// by 10 %: the image scene (the code draws the target, the shrunk code is the start).
#[allow(dead_code)]
fn shrunk_code(n: usize) -> (Vec<ifslab::model::Affine2>, Vec<f64>) {
    use ifslab::model::param::Parameterisation;
    let code = ifslab::model::random::sample_code(n, 3).expect("a valid sampler setting");
    let scaled: Vec<ifslab::model::Affine2> = code
        .maps
        .iter()
        .map(|m| ifslab::model::Affine2 {
            m: m.m,
            b: m.b * 0.9,
        })
        .collect();
    let theta = ifslab::model::Svd::default()
        .encode(&scaled)
        .expect("encodable maps");
    (code.maps, theta)
}

/// The SDF iteration's scene (`benches/sdf.rs` at 256² and depth 3): a Koch curve, σ 1.5,
/// cut-off 6σ; the target drawn from the truth, and the slightly moved pattern to fit.
#[allow(dead_code)]
struct KochSdfFixture {
    side: usize,
    sigma: f64,
    view: ifslab::render::sdf::SdfView,
    cfg: ifslab::render::sdf::SdfRenderConfig,
    current: ifslab::model::segment::Pattern,
    target: Vec<f64>,
}

#[allow(dead_code)]
fn koch_sdf_fixture(side: usize, depth: usize) -> KochSdfFixture {
    use ifslab::model::segment::{SegmentMap, builtin};
    use ifslab::render::sdf::{SdfRaster, SdfRenderConfig, SdfView};
    const SIGMA: f64 = 1.5;
    let koch_at = |to: [[f64; 2]; 2]| {
        let m = SegmentMap::between([0.0, 0.0], [1.0, 0.0], to[0], to[1]).expect("a map");
        builtin("koch")
            .expect("koch")
            .transformed(&m)
            .expect("a pattern")
    };
    let view = SdfView::unit_square(side);
    let truth = koch_at([[0.15, 0.4], [0.85, 0.4]]);
    let current = koch_at([[0.16, 0.41], [0.84, 0.38]]);
    let cfg = SdfRenderConfig {
        depth,
        cutoff: Some(6.0 * SIGMA),
    };
    let target = SdfRaster::render(&truth, &view, &cfg)
        .expect("render")
        .image(SIGMA);
    KochSdfFixture {
        side,
        sigma: SIGMA,
        view,
        cfg,
        current,
        target,
    }
}

/// The workloads' learnable-flame layer: 8 generators (spherical, handkerchief, swirl,
/// polar, disc, sinusoidal, linear + exponential, linear).
#[allow(dead_code)]
fn eight_generators() -> Vec<Vec<ifslab::model::flame::VariationKind>> {
    use ifslab::model::flame::VariationKind as V;
    vec![
        vec![V::Spherical],
        vec![V::Handkerchief],
        vec![V::Swirl],
        vec![V::Polar],
        vec![V::Disc],
        vec![V::Sinusoidal],
        vec![V::Linear, V::Exponential],
        vec![V::Linear],
    ]
}

/// One learnable-flame layer of `vars` (seed 7) over white, drawn with `cfg`, and a fixed
/// pseudo-random RGB target of `cfg`'s size.
#[allow(dead_code)]
fn learnable_flame_fixture(
    vars: &[Vec<ifslab::model::flame::VariationKind>],
    cfg: ifslab::render::flame_diff::DiffFlameConfig,
) -> (
    ifslab::model::flame::learnable::FlameStack,
    ifslab::render::flame_diff::DiffFlameConfig,
    Vec<f32>,
) {
    use ifslab::model::flame::learnable::{
        Background, FlameStack, Learn, LearnableFlame, LearnableInit,
    };
    let layer = LearnableFlame::random(vars, Learn::default(), &LearnableInit::default(), 7)
        .expect("a random flame");
    let st = FlameStack {
        layers: vec![layer],
        background: Background::Fixed([1.0; 3]),
    };
    let target: Vec<f32> = (0..3 * cfg.size * cfg.size)
        .map(|i| ((i * 7919) % 101) as f32 / 100.0)
        .collect();
    (st, cfg, target)
}

/// The workloads' flame setting: 100² (the default size), 200 × 200 samples.
#[allow(dead_code)]
fn workload_flame_config() -> ifslab::render::flame_diff::DiffFlameConfig {
    ifslab::render::flame_diff::DiffFlameConfig {
        trajectories: 200,
        steps: 200,
        ..ifslab::render::flame_diff::DiffFlameConfig::default()
    }
}
