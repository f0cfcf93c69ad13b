//! The differentiable flame pipeline: its reverse pass against central finite differences
//! for every kind of learnable parameter (pre-affine, variation weights, post-affine, final
//! transform, κ, colours, background), in f64 on a small problem; thread-count
//! independence; the painter and compositor on hand-computed pixels.

use ifslab::chaos::Isa;
use ifslab::model::flame::VariationKind as V;
use ifslab::model::flame::learnable::{
    Background, FlameStack, Learn, LearnableFlame, LearnableInit,
};
use ifslab::render::flame_diff::{
    DiffFlameConfig, GeneratorOrder, backward, backward_with_isa, forward, forward_with_isa, mse,
};

fn small_cfg() -> DiffFlameConfig {
    DiffFlameConfig {
        size: 12,
        // 9 a chunk: one group of the forward loop's side-by-side trajectories and one
        // trajectory alone.
        trajectories: 18,
        steps: 40,
        warmup: 3,
        chunks: 2,
    }
}

fn stack() -> FlameStack {
    let init = LearnableInit {
        translation: 0.6,
        scale: 0.6,
        final_translation: 0.2,
        kappa: 2.0,
    };
    let nonlinear = LearnableFlame::random(
        &[
            vec![V::Linear],
            vec![V::Spherical],
            vec![V::Handkerchief, V::Swirl],
            vec![V::Exponential],
            vec![V::Disc, V::Heart],
        ],
        Learn {
            weights: true,
            post: true,
        },
        &init,
        3,
    )
    .unwrap();
    let mut nonlinear = nonlinear;
    // Post maps away from the identity, a shear in the final transform, κ ≠ 2.
    for (i, g) in nonlinear.generators.iter_mut().enumerate() {
        g.post = [0.9, 0.05 * i as f64, -0.1, 0.8, 0.02, -0.03];
        for v in &mut g.variations {
            v.weight = 0.7;
        }
    }
    nonlinear.final_coefs = [0.8, 0.1, -0.05, 0.7, 0.05, -0.02];
    nonlinear.kappa_raw = 0.3;
    let linear = LearnableFlame::random(
        &[vec![V::Linear], vec![V::Linear], vec![V::Linear]],
        Learn::default(),
        &init,
        4,
    )
    .unwrap();
    FlameStack {
        layers: vec![nonlinear, linear],
        background: Background::Learned([0.2, -0.4, 0.1]),
    }
}

fn target(n: usize) -> Vec<f32> {
    (0..3 * n * n)
        .map(|i| (i * 7919 % 101) as f32 / 100.0)
        .collect()
}

fn loss(st: &FlameStack, cfg: &DiffFlameConfig, order: &GeneratorOrder, t: &[f32]) -> f64 {
    let f = forward(st, cfg, order).unwrap();
    mse(&f.image, t).unwrap().0
}

#[test]
fn reverse_pass_matches_finite_differences_for_every_parameter_kind() {
    let cfg = small_cfg();
    let st = stack();
    let order = GeneratorOrder::draw(&st, &cfg, 11);
    let t = target(cfg.size);
    let frame = forward(&st, &cfg, &order).unwrap();
    let (_, gimg) = mse(&frame.image, &t).unwrap();
    let grad = backward(&st, &cfg, &order, &frame, &gimg).unwrap();
    let theta = st.params();
    assert_eq!(grad.len(), theta.len());
    let h = 1e-6;
    let mut worst: f64 = 0.0;
    let mut nonzero = 0;
    for i in 0..theta.len() {
        let mut sp = st.clone();
        let mut tp = theta.clone();
        tp[i] += h;
        sp.set_params(&tp).unwrap();
        let lp = loss(&sp, &cfg, &order, &t);
        tp[i] -= 2.0 * h;
        sp.set_params(&tp).unwrap();
        let lm = loss(&sp, &cfg, &order, &t);
        let fd = (lp - lm) / (2.0 * h);
        let err = (fd - grad[i]).abs() / (1e-4 + fd.abs().max(grad[i].abs()));
        if fd.abs() > 1e-8 {
            nonzero += 1;
        }
        assert!(
            err < 1e-3,
            "θ[{i}]: analytic {} vs finite difference {fd} (relative error {err})",
            grad[i]
        );
        worst = worst.max(err);
    }
    // Most parameters must actually move the loss, or the test checks nothing.
    assert!(
        nonzero > theta.len() * 3 / 4,
        "{nonzero} of {} parameters move the loss",
        theta.len()
    );
    eprintln!(
        "worst relative error {worst:.2e} over {} parameters",
        theta.len()
    );
}

#[test]
fn images_and_gradients_do_not_depend_on_the_thread_count() {
    let cfg = DiffFlameConfig {
        size: 24,
        trajectories: 40,
        steps: 200,
        warmup: 10,
        chunks: 5,
    };
    let st = stack();
    let order = GeneratorOrder::draw(&st, &cfg, 5);
    let t = target(cfg.size);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let f = forward(&st, &cfg, &order).unwrap();
                let (_, g) = mse(&f.image, &t).unwrap();
                (
                    f.image.clone(),
                    backward(&st, &cfg, &order, &f, &g).unwrap(),
                )
            })
    };
    let (i1, g1) = run(1);
    let (i3, g3) = run(3);
    assert_eq!(i1, i3);
    assert_eq!(g1, g3);
}

#[test]
fn instruction_sets_give_the_same_bits() {
    // The AVX2+FMA loops (vector exponentials, 16-lane splat and gather runs) against the
    // portable ones, footprints inside the image and across its border (size 24: the
    // attractor spills over the edges).
    let cfg = DiffFlameConfig {
        size: 24,
        trajectories: 30,
        steps: 300,
        warmup: 10,
        chunks: 2,
    };
    let st = stack();
    let order = GeneratorOrder::draw(&st, &cfg, 9);
    let t = target(cfg.size);
    let run = |isa: Isa| {
        let f = forward_with_isa(&st, &cfg, &order, isa).unwrap();
        let (_, g) = mse(&f.image, &t).unwrap();
        let grad = backward_with_isa(&st, &cfg, &order, &f, &g, isa).unwrap();
        (f.image, grad)
    };
    let (ia, ga) = run(Isa::Portable);
    assert!(
        ia.iter().any(|&v| v != ia[0]),
        "a blank frame tests nothing"
    );
    if !Isa::Fma.is_available() {
        // Without AVX2+FMA the fast path must refuse clearly rather than run.
        let e = forward_with_isa(&st, &cfg, &order, Isa::Fma)
            .unwrap_err()
            .to_string();
        assert!(e.contains("AVX2"), "{e}");
        return;
    }
    let (ib, gb) = run(Isa::Fma);
    assert_eq!(
        ia.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        ib.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
    assert_eq!(
        ga.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        gb.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
}

#[test]
fn painter_and_compositor_follow_the_authors_formulas() {
    // One layer, one generator that maps everything to one point: every sample lands on the
    // centre of pixel (1, 1) of a 3×3 image, with C = colour·W (one generator).
    let cfg = DiffFlameConfig {
        size: 3,
        trajectories: 2,
        steps: 30,
        warmup: 5,
        chunks: 1,
    };
    let mut layer = LearnableFlame::random(
        &[vec![V::Linear]],
        Learn::default(),
        &LearnableInit::default(),
        1,
    )
    .unwrap();
    layer.generators[0].coefs = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    layer.final_coefs = [1.0, 0.0, 0.0, 1.0, -1.0 / 3.0, -1.0 / 3.0];
    layer.color_logits = vec![[1.0, -1.0, 0.5, 0.3]];
    let st = FlameStack {
        layers: vec![layer.clone()],
        background: Background::Fixed([1.0, 1.0, 1.0]),
    };
    let order = GeneratorOrder::draw(&st, &cfg, 0);
    let f = forward(&st, &cfg, &order).unwrap();
    // Centre pixel: w = Σ_j W_j (weight 1), the largest; α_w = 1.
    let b = &f.layers[0];
    let centre = 4;
    assert_eq!(b.w_max, b.pixels[centre][4]);
    let c = layer.color(0);
    let w = b.pixels[centre][4];
    let s = 1.0 / (1.0 + w);
    let alpha = c[3] * w * s;
    for (ch, &cc) in c.iter().take(3).enumerate() {
        let rgb = cc * w * s * alpha;
        let expect = 1.0 * (1.0 - alpha) + rgb;
        let got = f.image[ch * 9 + centre];
        assert!(
            (got - expect).abs() < 1e-12,
            "channel {ch}: {got} vs {expect}"
        );
    }
    // A neighbour gets weight e^{−2} per sample.
    let n = b.pixels[1][4];
    assert!((n / w - (-2.0f64).exp()).abs() < 1e-12);
}
