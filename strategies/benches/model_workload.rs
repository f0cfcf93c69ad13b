//! A fixed workload comparing the image problem's two ways of evaluating affine maps, by
//! instruction count (a shared machine makes wall-clock too noisy for a few per cent): the
//! affine-only path the problem used before map families existed (θ → SVD decode → `(n, 6)`
//! tensor → `SplatOp::new` → objective on `Affine2` → chain rule) against the path it uses now
//! for every family (`AffineModel` behind `AnyModel`: a pass of the one image problem's
//! instance, `SplatProblem` — decode, the splat as a `Renderer`, the objective's candle graph to
//! the image, the splat's reverse pass, the regulariser as the prior, `ImageModel::backward`).
//! Both in one build, same setup.
//!
//! ```sh
//! cargo bench -p ifslab-strategies --bench model_workload --no-run   # prints the path
//! RAYON_NUM_THREADS=1 valgrind --tool=cachegrind --cache-sim=no \
//!     target/release/deps/model_workload-<hash> model 4
//! ```
//!
//! Stages `direct` and `model`, each run N times after the setup; the per-call cost is the
//! difference between runs with N and N + k calls, divided by k (BENCHMARKS.md §2).

use std::hint::black_box;

use candle_core::{DType, Device, Tensor, Var};
use ifslab::loss::{LossConfig, Objective};
use ifslab::model::Svd;
use ifslab::model::param::Parameterisation;
use ifslab::render::splat::{self, Blend, SplatConfig, SplatOp, maps_from_tensor, maps_to_tensor};
use ifslab_strategies::problems::image::config::MapProbabilities;
use ifslab_strategies::problems::image::{AffineModel, AnyModel, ImageRendering};

include!("../../benches/common/fixtures.rs");

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    let (stage, calls) = stage_and_calls("model_workload <setup|direct|model> <calls>");
    let cfg = SplatConfig {
        width: 256,
        height: 256,
        supersample: 2,
        sigma: 1.0,
        blend: Blend::Coverage,
        ..SplatConfig::default()
    };
    let (_, theta) = shrunk_code(10);
    let p = Svd::default();
    let maps = p.decode(&theta).expect("decodable θ");
    let dev = Device::Cpu;
    let (target, _) = splat::forward::<f32>(&cfg, &maps, 99).expect("forward");
    let target_t = Tensor::from_vec(target, (cfg.height, cfg.width), &dev).expect("tensor");
    let loss = LossConfig {
        lpips_weight: 0.0,
        ..LossConfig::default()
    };
    let objective = Objective::new(loss, &target_t).expect("objective");
    let model = AffineModel(Box::new(Svd::default()));
    let any: &dyn AnyModel = &model;
    let mut sink = 0.0f64;
    // Both stages render the chaos game of draw `call` of a run seeded RUN_SEED: the
    // model is given the run's seed and the draw and asks the splat for it.
    const RUN_SEED: u64 = 7;
    for call in 0..calls {
        let seed = ifslab::chaos::mix_seed(RUN_SEED, call as u64);
        sink += match stage.as_str() {
            "direct" => {
                let m = p.decode(&theta).expect("decode");
                let var = Var::from_tensor(&maps_to_tensor(&m, DType::F32, &dev).expect("maps"))
                    .expect("var");
                let pred = var
                    .as_tensor()
                    .apply_op1(SplatOp::new(cfg.clone(), seed))
                    .expect("splat");
                let ev = objective.evaluate(&pred, &m).expect("loss");
                let grads = ev.image_total.backward().expect("backward");
                let g = grads.get(var.as_tensor()).expect("a gradient for the maps");
                let mut gm = maps_from_tensor(g).expect("maps gradient");
                for (g, r) in gm.iter_mut().zip(&ev.map_grad) {
                    g.m += r.m;
                    g.b += r.b;
                }
                p.backward(&theta, &gm).expect("chain rule")[0]
            }
            "model" => {
                let rendering = ImageRendering {
                    splat: cfg.clone(),
                    sigma_schedule: None,
                    probabilities: MapProbabilities::Uniform,
                    clamp: false,
                    seed: RUN_SEED,
                };
                any.evaluate(&theta, &rendering, &objective, call as u64)
                    .expect("evaluate")
                    .grad[0]
            }
            "setup" => 0.0,
            s => panic!("unknown stage {s}"),
        };
    }
    eprintln!("{stage} × {calls} [{}]", black_box(sink));
}
