//! A fixed workload for comparing two builds by instruction count: one `evaluate` (loss and
//! gradient) of each differentiable problem, the way the driver calls it — the image
//! problem (affine maps under the SVD parameterisation, splat at the demo setting: 96², 4×,
//! σ = 1, 1000 × 110 trajectories, MS-MSE + D-SSIM, f32), the SDF problem (Koch at depth 3,
//! 256², σ = 1.5, the default loss with its 6σ cut-off) and the flame problem (8 generators
//! with trigonometric variations, 100², 200 × 200 samples, the authors' MSE) and the
//! multi-view problem (the 3-D fern's maps against 8 turntable views of the tetrahedron,
//! 128², 100 000 points, `invert3d`'s default terms, f32).
//!
//! ```sh
//! cargo bench -p ifslab-strategies --bench problem_workload --no-run   # prints the path
//! RAYON_NUM_THREADS=1 valgrind --tool=cachegrind --cache-sim=no \
//!     target/release/deps/problem_workload-<hash> sdf 3
//! ```
//!
//! Stages `setup`, `image`, `sdf`, `flame`, `image3d`, each run N times after the setup; the
//! per-call cost is the difference between runs with N and N + k calls, divided by k
//! (BENCHMARKS.md §10). It prints a fingerprint of every loss's and gradient's bits, so two
//! builds can be checked to compute the same numbers.

use std::hint::black_box;

use ifslab::image::Image;
use ifslab::loss::LossConfig;
use ifslab::model::Svd;
use ifslab::model::map3::{DiffMap, SvdMap3, fern_3d, sierpinski_tetrahedron};
use ifslab::render::Renderer;
use ifslab::render::splat;
use ifslab::render::splat3d::{Lens, MultiViewConfig, MultiViewSplat, turntable};
use ifslab_strategies::driver::Differentiable;
use ifslab_strategies::problems::flame::{FlameLoss, FlameProblem, Rates};
use ifslab_strategies::problems::image::{AffineModel, ImageProblem};
use ifslab_strategies::problems::image3d::{Image3dConfig, Image3dProblem, Views};
use ifslab_strategies::problems::sdf::{SdfLossConfig, SdfProblem};

include!("../../benches/common/fixtures.rs");

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    let (stage, calls) =
        stage_and_calls("problem_workload <setup|image|sdf|flame|image3d> <calls>");
    let (problem, theta): (Box<dyn Differentiable>, Vec<f64>) = match stage.as_str() {
        "image" | "setup" => image(),
        "sdf" => sdf(),
        "flame" => flame(),
        "image3d" => image3d(),
        s => panic!("unknown stage {s}"),
    };
    let mut sink = 0.0f64;
    // FNV-1a over the bits of every loss and gradient entry.
    let mut bits = 0xcbf2_9ce4_8422_2325u64;
    if stage != "setup" {
        for call in 0..calls {
            let e = problem.evaluate(&theta, call as u64).expect("evaluate");
            sink += e.loss;
            for v in std::iter::once(e.loss).chain(e.grad) {
                bits = (bits ^ v.to_bits()).wrapping_mul(0x100_0000_01b3);
            }
        }
    }
    eprintln!("{stage} × {calls} [{}] bits {bits:016x}", black_box(sink));
}

fn image() -> (Box<dyn Differentiable>, Vec<f64>) {
    let cfg = demo_splat_config();
    let (truth, theta) = shrunk_code(10);
    let p = Svd::default();
    let (target, _) = splat::forward::<f32>(&cfg, &truth, 99).expect("forward");
    let loss = LossConfig {
        lpips_weight: 0.0,
        ..LossConfig::default()
    };
    let target = Image::grey(cfg.width as u32, cfg.height as u32, target).expect("a target");
    let problem = ImageProblem::new(Box::new(AffineModel(Box::new(p))), cfg, loss, target, 7)
        .expect("a problem");
    (Box::new(problem), theta)
}

fn sdf() -> (Box<dyn Differentiable>, Vec<f64>) {
    let KochSdfFixture {
        side,
        sigma,
        view,
        cfg,
        current,
        target,
    } = koch_sdf_fixture(256, 3);
    assert_eq!(target.len(), side * side);
    let theta = current.flat_points();
    let target = Image::grey(side as u32, side as u32, target).expect("a target");
    let problem = SdfProblem::new(
        current,
        target,
        view,
        cfg.depth,
        sigma,
        SdfLossConfig::default(),
    )
    .expect("a problem");
    (Box::new(problem), theta)
}

fn flame() -> (Box<dyn Differentiable>, Vec<f64>) {
    let (st, cfg, target) = learnable_flame_fixture(&eight_generators(), workload_flame_config());
    let theta = st.params();
    let side = cfg.size as u32;
    let target = Image::new(side, side, 3, target).expect("a target");
    let problem = FlameProblem::new(
        st,
        cfg,
        target,
        5,
        1,
        &Rates::default(),
        FlameLoss::default(),
    )
    .expect("a problem");
    (Box::new(problem), theta)
}

fn image3d() -> (Box<dyn Differentiable>, Vec<f64>) {
    let side = 128;
    let cameras = turntable(
        8,
        25.0,
        2.6,
        Lens::pinhole_fov(50f64.to_radians(), side, side),
        side,
        side,
    )
    .expect("cameras");
    let cfg = MultiViewConfig::default();
    let truth = SvdMap3::from_code(&sierpinski_tetrahedron(), 1e-6).expect("maps");
    let target = MultiViewSplat::<SvdMap3, f32>::new(cfg.clone(), cameras.clone())
        .expect("a splat")
        .forward(&truth, &99)
        .expect("forward")
        .0;
    let n = cameras.len() as u32;
    let target = Image::new(side as u32, side as u32, n, target).expect("a target");
    let views = Views::new(cameras, target).expect("views");
    let maps = SvdMap3::from_code(&fern_3d().0, 1e-6).expect("maps");
    let theta: Vec<f64> = maps.iter().flat_map(|m| m.params()).collect();
    let d = Image3dConfig::default();
    let problem = Image3dProblem::<f32>::new(&maps, &views, cfg, d.loss(), 0)
        .and_then(|p| p.with_ink(d.ink, d.ink_slack))
        .and_then(|p| p.with_volume(d.volume))
        .expect("a problem")
        .with_map_choice(d.probabilities);
    (Box::new(problem), theta)
}
