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
//! `backward` (splat reverse pass), `iteration` (θ → op → loss → backward → chain rule);
//! the same at the demo setting (`demo-generation`, `demo-backward`, `demo-iteration`: 96²,
//! 4×, σ = 1, coverage, 1000 × 110 trajectories, what `ifslab demo` runs); and the other
//! renderers' hot loops: `flame-mixed` and `flame-linear` (the flame renderer on the
//! `m05` and `v00` fixtures of `benches/flame.rs` at 256², quality 10), `flame-learn`
//! (one forward + reverse pass of a learnable flame, 8 generators with trigonometric
//! variations, 100², 200 × 200 samples), `sdf` (one SDF fit iteration, Koch at depth 3,
//! 256², cut-off 6σ, as `benches/sdf.rs`).
//! The per-call cost is the difference between runs with N and N + k calls, divided by k
//! (BENCHMARKS.md, "The affine path through the generic map trait").

use std::hint::black_box;

use candle_core::{DType, Device, Tensor, Var};
use ifslab::loss::{ImageLoss, LossConfig, MsMse, Objective};
use ifslab::model::Svd;
use ifslab::model::flame::read_flames;
use ifslab::model::param::Parameterisation;
use ifslab::render::flame::{FlameRenderConfig, render_flame};
use ifslab::render::flame_diff::{self, GeneratorOrder};
use ifslab::render::sdf::SdfRaster;
use ifslab::render::splat::{self, Blend, SplatConfig, SplatOp, maps_from_tensor, maps_to_tensor};

include!("common/fixtures.rs");

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

const USAGE: &str = "usage: workload <stage> <calls>; stages: setup, generation, backward, \
                     iteration, demo-generation, demo-backward, demo-iteration, flame-mixed, \
                     flame-linear, flame-learn, sdf";

const STAGES: [&str; 11] = [
    "setup",
    "generation",
    "backward",
    "iteration",
    "demo-generation",
    "demo-backward",
    "demo-iteration",
    "flame-mixed",
    "flame-linear",
    "flame-learn",
    "sdf",
];

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
    if !STAGES.contains(&stage) {
        exit(&format!("unknown stage {stage}"));
    }
    match stage {
        "flame-mixed" | "flame-linear" => return flame(stage, calls),
        "flame-learn" => return flame_learn(calls),
        "sdf" => return sdf(calls),
        _ => {}
    }
    let (stage, cfg) = match stage.strip_prefix("demo-") {
        // `ifslab demo`'s splat (BENCHMARKS.md §2, "demo setting").
        Some(s) => (s, demo_splat_config()),
        None => (
            stage,
            SplatConfig {
                width: 1024,
                height: 1024,
                supersample: 5,
                sigma: 2.5,
                blend: Blend::Coverage,
                ..SplatConfig::default()
            },
        ),
    };
    let (_, theta) = shrunk_code(10);
    let p = Svd::default();
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
    report(stage, calls, start, sink);
}

fn report(stage: &str, calls: usize, start: std::time::Instant, sink: usize) {
    eprintln!(
        "{stage} × {calls}: {:.1} ms per call (wall) [{}]",
        start.elapsed().as_secs_f64() * 1e3 / calls.max(1) as f64,
        black_box(sink)
    );
}

/// The flame renderer on a fixture of `benches/flame.rs`, reframed to 256² at quality 10
/// (655 k samples): `m05` (polar, eyefish, fisheye, disc2, waves2) or `v00` (linear).
fn flame(stage: &str, calls: usize) {
    let name = if stage == "flame-mixed" { "m05" } else { "v00" };
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/flame/images")
        .join(format!("{name}.flame"));
    let mut f = read_flames(&path).expect("fixture").remove(0);
    f.scale *= 256.0 / f.size[1] as f64;
    f.size = [256, 256];
    f.quality = 10.0;
    let start = std::time::Instant::now();
    let mut sink = 0usize;
    for call in 0..calls {
        let cfg = FlameRenderConfig {
            seed: call as u64,
            ..FlameRenderConfig::default()
        };
        sink += render_flame(&f, &cfg, None).expect("render").pixels.len();
    }
    report(stage, calls, start, sink);
}

/// One gradient step of a learnable flame: 8 generators (spherical, handkerchief, swirl,
/// polar, disc, sinusoidal, julia-free trigonometric ones) at 100², 200 × 200 samples.
fn flame_learn(calls: usize) {
    let (st, cfg, target) = learnable_flame_fixture(&eight_generators(), workload_flame_config());
    let start = std::time::Instant::now();
    let mut sink = 0usize;
    for call in 0..calls {
        let order = GeneratorOrder::draw(&st, &cfg, call as u64);
        let f = flame_diff::forward(&st, &cfg, &order).expect("forward");
        let (_, gi) = flame_diff::mse(&f.image, &target).expect("mse");
        sink += flame_diff::backward(&st, &cfg, &order, &f, &gi)
            .expect("backward")
            .len();
    }
    report("flame-learn", calls, start, sink);
}

/// One SDF fit iteration as `benches/sdf.rs` (Koch, depth 3, 256², cut-off 6σ).
fn sdf(calls: usize) {
    let KochSdfFixture {
        side,
        sigma,
        view,
        cfg,
        current,
        target,
    } = koch_sdf_fixture(256, 3);
    let start = std::time::Instant::now();
    let mut sink = 0usize;
    for _ in 0..calls {
        let r = SdfRaster::render(&current, &view, &cfg).expect("render");
        let img = r.image(sigma);
        let (_, g) = MsMse::new(4)
            .value_and_grad::<f64>(&img, &target, side, side)
            .expect("loss");
        let gd = r.image_backward(sigma, &g);
        sink += r.backward(&current, &gd).expect("backward").len();
    }
    report("sdf", calls, start, sink);
}

fn exit(msg: &str) -> ! {
    eprintln!("{msg}\n{USAGE}");
    std::process::exit(2)
}
