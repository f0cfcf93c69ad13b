//! The sampling state each problem asks its renderer for (`ifslab::render::Sampler`) gives
//! the bits it gave before the sampler existed: loss and gradient of a few iterations of the
//! image, SDF and flame problems, hashed, against the values of commit d9a23219 (where each
//! problem drew its seeds itself). The flame problem redraws its generator order every two
//! iterations here, so a redraw is among the pinned iterations.

use ifslab::chaos::ChaosGame;
use ifslab::image::Image;
use ifslab::loss::LossConfig;
use ifslab::model::Svd;
use ifslab::model::flame::VariationKind as V;
use ifslab::render::flame_diff::DiffFlameConfig;
use ifslab::render::splat::{self, Blend, SplatConfig};
use ifslab_strategies::driver::Differentiable;
use ifslab_strategies::optim::annealing::Anneal;
use ifslab_strategies::problems::flame::{FlameLoss, FlameProblem, Rates};
use ifslab_strategies::problems::image::{AffineModel, ImageProblem};
use ifslab_strategies::problems::sdf::{SdfLossConfig, SdfProblem};

include!("../../benches/common/fixtures.rs");

/// FNV-1a over the bits of the loss and the gradient of iterations `0..4`.
fn fingerprint(problem: &dyn Differentiable, theta: &[f64]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |v: f64| {
        for b in v.to_bits().to_le_bytes() {
            h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    };
    for iter in 0..4 {
        let e = problem.evaluate(theta, iter).expect("evaluate");
        eat(e.loss);
        e.grad.iter().for_each(|&g| eat(g));
        e.terms.iter().for_each(|&(_, v)| eat(v));
    }
    h
}

fn image() -> (ImageProblem, Vec<f64>) {
    let cfg = SplatConfig {
        width: 32,
        height: 32,
        supersample: 2,
        sigma: 1.0,
        blend: Blend::Coverage,
        game: ChaosGame {
            trajectories: 200,
            length: 60,
            ..ChaosGame::default()
        },
        ..SplatConfig::default()
    };
    let (truth, theta) = shrunk_code(3);
    let p = Svd::default();
    let (target, _) = splat::forward::<f32>(&cfg, &truth, 99).expect("forward");
    let loss = LossConfig {
        lpips_weight: 0.0,
        ..LossConfig::default()
    };
    let target = Image::grey(cfg.width as u32, cfg.height as u32, target).expect("a target");
    let problem = ImageProblem::new(Box::new(AffineModel(Box::new(p))), cfg, loss, target, 7)
        .expect("a problem");
    (problem, theta)
}

#[test]
fn image_problem_keeps_its_bits() {
    let (problem, theta) = image();
    let mut h = fingerprint(&problem, &theta);
    // The seeded renders outside the gradient: evaluation renders and annealing's cost.
    for stream in [0, 5] {
        let img = problem.render(&theta, stream).expect("render");
        h ^= img
            .iter()
            .fold(0u64, |a, &v| a.rotate_left(5) ^ v.to_bits() as u64);
        h = h.rotate_left(7) ^ problem.anneal_cost(&theta, stream, 0.5).unwrap().to_bits();
    }
    println!("image {h:#018x}");
    assert_eq!(h, IMAGE);
}

#[test]
fn sdf_problem_keeps_its_bits() {
    let KochSdfFixture {
        sigma,
        view,
        cfg,
        current,
        target,
        ..
    } = koch_sdf_fixture(64, 2);
    let theta = current.flat_points();
    let target = Image::square(view.width, target).expect("a target");
    let problem = SdfProblem::new(
        current,
        target,
        view,
        cfg.depth,
        sigma,
        SdfLossConfig::default(),
    )
    .expect("a problem");
    let h = fingerprint(&problem, &theta);
    println!("sdf {h:#018x}");
    assert_eq!(h, SDF);
}

#[test]
fn flame_problem_keeps_its_bits() {
    let vars = [vec![V::Spherical], vec![V::Swirl], vec![V::Linear]];
    let (st, cfg, target) = learnable_flame_fixture(
        &vars,
        DiffFlameConfig {
            size: 24,
            trajectories: 40,
            steps: 40,
            ..DiffFlameConfig::default()
        },
    );
    let theta = st.params();
    let side = cfg.size as u32;
    let target = Image::new(side, side, 3, target).expect("a target");
    let problem = FlameProblem::new(
        st,
        cfg,
        target,
        5,
        2,
        &Rates::default(),
        FlameLoss::default(),
    )
    .expect("a problem");
    let mut h = fingerprint(&problem, &theta);
    // Back to an earlier epoch after a later one: the order is redrawn, the same.
    h = h.rotate_left(7) ^ problem.cost(&theta, 1).unwrap().to_bits();
    println!("flame {h:#018x}");
    assert_eq!(h, FLAME);
}

const IMAGE: u64 = 0x828e_b603_41dd_4d67;
const SDF: u64 = 0x601c_97cf_3a7f_2ae5;
const FLAME: u64 = 0x8835_5358_3cd0_110f;
