//! A fixed workload for comparing two builds by instruction count or CPU time, where
//! wall-clock medians are too noisy (a shared machine): one stage of the paper-setting
//! iteration (1024², 5×, σ = 2.5, 2000 × 250 trajectories, the splat bench's 10-map code,
//! f32), run a given number of times after a fixed setup.
//!
//! ```sh
//! cargo bench --bench workload --no-run        # prints the executable's path
//! RAYON_NUM_THREADS=1 valgrind --tool=cachegrind --cache-sim=no \
//!     target/release/deps/workload-<hash> iteration 2
//! ```
//!
//! Stages: `setup` (nothing after the setup), `generation` (chaos game with tape),
//! `backward` (splat reverse pass), `iteration` (θ → op → loss → backward → chain rule).
//! The per-call cost is the difference between runs with N and N + k calls, divided by k
//! (BENCHMARKS.md, "The affine path through the generic map trait").

use std::hint::black_box;

use candle_core::{DType, Device, Tensor, Var};
use ifslab::loss::{LossConfig, Objective};
use ifslab::model::param::Parameterisation;
use ifslab::model::random::sample_code;
use ifslab::model::{Affine2, Svd};
use ifslab::render::splat::{self, Blend, SplatConfig, SplatOp, maps_from_tensor, maps_to_tensor};

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

const USAGE: &str = "usage: workload <setup|generation|backward|iteration> <calls>";

fn main() {
    // `cargo bench` passes `--bench`; everything else is ours.
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let (stage, calls) = match args.as_slice() {
        [s, n] => match n.parse::<usize>() {
            Ok(n) => (s.as_str(), n),
            Err(_) => exit(&format!("calls must be a whole number, got {n}")),
        },
        // Run under `cargo bench` with no arguments: one cheap pass so the harness succeeds.
        [] => ("setup", 0),
        _ => exit("expected a stage and a number of calls"),
    };
    if !["setup", "generation", "backward", "iteration"].contains(&stage) {
        exit(&format!("unknown stage {stage}"));
    }
    let cfg = SplatConfig {
        width: 1024,
        height: 1024,
        supersample: 5,
        sigma: 2.5,
        blend: Blend::Coverage,
        ..SplatConfig::default()
    };
    let code = sample_code(10, 3).expect("a valid sampler setting");
    let p = Svd::default();
    let scaled: Vec<Affine2> = code
        .maps
        .iter()
        .map(|m| Affine2 {
            m: m.m,
            b: m.b * 0.9,
        })
        .collect();
    let theta = p.encode(&scaled).expect("encodable maps");
    let maps = p.decode(&theta).expect("decodable θ");
    let dev = Device::Cpu;
    let (target, tape) = splat::forward::<f32>(&cfg, &maps, 99).expect("forward");
    let grad: Vec<f32> = target.iter().map(|v| v - 0.3).collect();
    let target_t = Tensor::from_vec(target, (cfg.height, cfg.width), &dev).expect("tensor");
    let loss = LossConfig {
        lpips_weight: 0.0,
        ..LossConfig::default()
    };
    let objective = Objective::new(loss, &target_t).expect("objective");
    let start = std::time::Instant::now();
    let mut sink = 0usize;
    for call in 0..calls {
        let seed = call as u64;
        sink += match stage {
            "generation" => splat::trajectories::run(&cfg.game, &maps, None, seed)
                .expect("generation")
                .states
                .len(),
            "backward" => splat::backward(&cfg, &maps, &tape, &grad)
                .expect("backward")
                .len(),
            "iteration" => {
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
                let gm = maps_from_tensor(g).expect("maps gradient");
                p.backward(&theta, &gm).expect("chain rule").len()
            }
            _ => 0,
        };
    }
    eprintln!(
        "{stage} × {calls}: {:.1} ms per call (wall) [{}]",
        start.elapsed().as_secs_f64() * 1e3 / calls.max(1) as f64,
        black_box(sink)
    );
}

fn exit(msg: &str) -> ! {
    eprintln!("{msg}\n{USAGE}");
    std::process::exit(2)
}
