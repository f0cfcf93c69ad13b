//! A fixed workload for comparing two builds by instruction count: one `evaluate` (loss and
//! gradient) of each differentiable problem, the way the driver calls it — the image
//! problem (affine maps under the SVD parameterisation, splat at the demo setting: 96², 4×,
//! σ = 1, 1000 × 110 trajectories, MS-MSE + D-SSIM, f32), the SDF problem (Koch at depth 3,
//! 256², σ = 1.5, the default loss with its 6σ cut-off) and the flame problem (8 generators
//! with trigonometric variations, 100², 200 × 200 samples, the authors' MSE).
//!
//! ```sh
//! cargo bench -p ifslab-strategies --bench problem_workload --no-run   # prints the path
//! RAYON_NUM_THREADS=1 valgrind --tool=cachegrind --cache-sim=no \
//!     target/release/deps/problem_workload-<hash> sdf 3
//! ```
//!
//! Stages `setup`, `image`, `sdf`, `flame`, each run N times after the setup; the per-call
//! cost is the difference between runs with N and N + k calls, divided by k (BENCHMARKS.md
//! §10).

use std::hint::black_box;

use ifslab::loss::LossConfig;
use ifslab::model::Svd;
use ifslab::render::splat;
use ifslab_strategies::driver::Differentiable;
use ifslab_strategies::problems::flame::{FlameLoss, FlameProblem, Rates};
use ifslab_strategies::problems::image::{AffineModel, ImageProblem};
use ifslab_strategies::problems::sdf::{SdfLossConfig, SdfProblem};

include!("../../benches/common/fixtures.rs");

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    let (stage, calls) = stage_and_calls("problem_workload <setup|image|sdf|flame> <calls>");
    let (problem, theta): (Box<dyn Differentiable>, Vec<f64>) = match stage.as_str() {
        "image" | "setup" => image(),
        "sdf" => sdf(),
        "flame" => flame(),
        s => panic!("unknown stage {s}"),
    };
    let mut sink = 0.0f64;
    if stage != "setup" {
        for call in 0..calls {
            sink += problem
                .evaluate(&theta, call as u64)
                .expect("evaluate")
                .loss;
        }
    }
    eprintln!("{stage} × {calls} [{}]", black_box(sink));
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
