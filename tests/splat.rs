//! The fused splat op: gradients against central finite differences (f64, ~2k points,
//! small images) in both blend modes, with and without supersampling, fitted and fixed
//! framing; the candle wrapper gives the same gradients; results do not depend on threads.

use candle_core::{DType, Device, Var};
use ifslab::chaos::ChaosGame;
use ifslab::model::{Affine2, Window};
use ifslab::render::splat::{
    self, Blend, SplatConfig, SplatOp, SplatView, maps_from_tensor, maps_to_tensor,
};

fn maps() -> Vec<Affine2> {
    vec![
        Affine2::new(0.45, 0.1, -0.05, 0.5, -0.4, -0.3),
        Affine2::new(0.5, -0.12, 0.08, 0.42, 0.45, -0.2),
        Affine2::new(0.38, 0.05, 0.1, 0.4, 0.05, 0.5),
    ]
}

fn config(blend: Blend, supersample: usize, framing: SplatView) -> SplatConfig {
    SplatConfig {
        width: 24,
        height: 20,
        supersample,
        sigma: 1.3,
        radius: 3.0,
        blend,
        alpha_max: 0.99,
        game: ChaosGame {
            trajectories: 20,
            length: 110,
            warmup: 10,
            start_half_width: 2.0,
            seed: 0,
        },
        framing,
        device: Default::default(),
    }
}

/// Fixed pseudo-random weights W so that L = Σ W ⊙ image and ∂L/∂image = W.
fn weights(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| ((i as f64 * 12.9898).sin() * 43758.5453).fract() - 0.25)
        .collect()
}

fn loss(cfg: &SplatConfig, maps: &[Affine2], w: &[f64]) -> f64 {
    let (img, _) = splat::forward::<f64>(cfg, maps, 7).unwrap();
    img.iter().zip(w).map(|(a, b)| a * b).sum()
}

fn check_gradient(cfg: &SplatConfig) {
    let maps = maps();
    let w = weights(cfg.width * cfg.height);
    let (img, tape) = splat::forward::<f64>(cfg, &maps, 7).unwrap();
    assert!(
        img.iter().any(|&v| v > 0.05),
        "the render must not be empty"
    );
    let grad = splat::backward(cfg, &maps, &tape, &w).unwrap();
    let mut worst = 0.0f64;
    let mut scale = 0.0f64;
    for i in 0..maps.len() {
        for k in 0..6 {
            // Small h: the footprint's cut-off at 3σ is continuous but has a kink, which a
            // larger step would straddle for some of the ~10⁵ point–pixel pairs.
            let h = 1e-7;
            let bump = |d: f64| {
                let mut m = maps.clone();
                let mut c = m[i].coefficients();
                c[k] += d;
                m[i] = Affine2::from_coefficients(&c);
                m
            };
            let fd = (loss(cfg, &bump(h), &w) - loss(cfg, &bump(-h), &w)) / (2.0 * h);
            let an = grad[i * 6 + k];
            worst = worst.max((fd - an).abs());
            scale = scale.max(fd.abs());
            assert!(
                (fd - an).abs() <= 2e-4 * (1.0 + fd.abs()),
                "{:?} s={} map {i} coef {k}: analytic {an} vs finite difference {fd}",
                cfg.blend,
                cfg.supersample
            );
        }
    }
    assert!(
        scale > 1e-3,
        "gradients should not all vanish (max |fd| = {scale})"
    );
    eprintln!(
        "{:?} s={}: max |analytic − fd| = {worst:.2e} (max |fd| = {scale:.2e})",
        cfg.blend, cfg.supersample
    );
}

#[test]
fn coverage_gradient_matches_finite_differences() {
    check_gradient(&config(Blend::Coverage, 1, SplatView::default()));
}

#[test]
fn coverage_gradient_with_supersampling_matches_finite_differences() {
    check_gradient(&config(Blend::Coverage, 3, SplatView::default()));
}

#[test]
fn additive_gradient_matches_finite_differences() {
    check_gradient(&config(Blend::Additive, 1, SplatView::default()));
    check_gradient(&config(Blend::Additive, 2, SplatView::default()));
}

#[test]
fn fixed_window_gradient_matches_finite_differences() {
    let window = SplatView::Window(Window {
        min: [-1.1, -1.0],
        max: [1.3, 1.0],
    });
    check_gradient(&config(Blend::Coverage, 2, window));
}

#[test]
fn candle_op_gives_the_same_image_and_gradient() {
    let cfg = config(Blend::Coverage, 2, SplatView::default());
    let maps = maps();
    let w = weights(cfg.width * cfg.height);
    let (img, tape) = splat::forward::<f64>(&cfg, &maps, 7).unwrap();
    let direct = splat::backward(&cfg, &maps, &tape, &w).unwrap();

    let dev = Device::Cpu;
    let var = Var::from_tensor(&maps_to_tensor(&maps, DType::F64, &dev).unwrap()).unwrap();
    let image = var
        .as_tensor()
        .apply_op1(SplatOp::new(cfg.clone(), 7))
        .unwrap();
    assert_eq!(image.dims(), &[20, 24]);
    let got: Vec<f64> = image.flatten_all().unwrap().to_vec1().unwrap();
    assert_eq!(got, img);
    let wt = candle_core::Tensor::from_vec(w, (20, 24), &dev).unwrap();
    let l = (image * wt).unwrap().sum_all().unwrap();
    let grads = l.backward().unwrap();
    let g = maps_from_tensor(grads.get(var.as_tensor()).unwrap()).unwrap();
    let g: Vec<f64> = g.iter().flat_map(|m| m.coefficients()).collect();
    assert_eq!(g.len(), direct.len());
    for (x, y) in g.iter().zip(&direct) {
        assert!((x - y).abs() < 1e-12, "{x} vs {y}");
    }
    // f32 tensors work too and agree to single precision.
    let var32 = Var::from_tensor(&maps_to_tensor(&maps, DType::F32, &dev).unwrap()).unwrap();
    let img32 = var32.as_tensor().apply_op1(SplatOp::new(cfg, 7)).unwrap();
    let v32: Vec<f32> = img32.flatten_all().unwrap().to_vec1().unwrap();
    for (a, b) in v32.iter().zip(&img) {
        assert!((*a as f64 - b).abs() < 1e-4);
    }
}

#[test]
fn forward_and_backward_do_not_depend_on_thread_count() {
    let mut cfg = config(Blend::Coverage, 2, SplatView::default());
    cfg.width = 70;
    cfg.height = 50;
    cfg.game.trajectories = 300;
    let maps = maps();
    let w: Vec<f32> = weights(70 * 50).iter().map(|&x| x as f32).collect();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let (img, tape) = splat::forward::<f32>(&cfg, &maps, 3).unwrap();
                let g = splat::backward(&cfg, &maps, &tape, &w).unwrap();
                (img, g)
            })
    };
    let (a, ga) = run(1);
    let (b, gb) = run(2);
    assert_eq!(a, b);
    assert_eq!(ga, gb);
}

#[test]
fn bad_inputs_are_refused() {
    let cfg = config(Blend::Coverage, 1, SplatView::default());
    let mut m = maps();
    m[1].m[(0, 0)] = f64::NAN;
    assert!(splat::forward::<f32>(&cfg, &m, 0).is_err());
    assert!(splat::forward::<f32>(&cfg, &[] as &[Affine2], 0).is_err());
    let bad = SplatConfig {
        sigma: -1.0,
        ..cfg.clone()
    };
    let e = splat::forward::<f32>(&bad, &maps(), 0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("sigma"), "{e}");
    let diverging = vec![Affine2::new(2.5, 0.0, 0.0, 2.5, 1.0, 0.0); 2];
    let long = SplatConfig {
        game: ChaosGame {
            length: 400,
            ..cfg.game.clone()
        },
        ..cfg
    };
    assert!(matches!(
        splat::forward::<f32>(&long, &diverging, 0),
        Err(ifslab::Error::Divergent { .. })
    ));
}

/// Large tile buffers are recycled between calls: a recycled buffer must start from the
/// same state as a fresh one, so repeating a call after a different one gives the same bits
/// (forward and reverse), and so does a call after the pool is emptied.
#[test]
fn recycled_buffers_do_not_leak_state_between_calls() {
    let cfg = SplatConfig {
        width: 128,
        height: 128,
        supersample: 5,
        ..config(Blend::Coverage, 5, SplatView::default())
    };
    let other: Vec<Affine2> = maps()
        .iter()
        .map(|m| Affine2 {
            m: m.m * 0.9,
            b: m.b * 1.1,
        })
        .collect();
    let run = |m: &[Affine2]| {
        let (img, tape) = splat::forward::<f32>(&cfg, m, 4).unwrap();
        let g: Vec<f32> = img.iter().map(|v| v - 0.25).collect();
        let grads = splat::backward(&cfg, m, &tape, &g).unwrap();
        (img, grads)
    };
    let first = run(&maps());
    let _ = run(&other);
    assert_eq!(run(&maps()), first);
    splat::release_buffers();
    assert_eq!(run(&maps()), first);
}

/// Map probabilities reach the chaos game: with all the weight on one map every kept point
/// is (within the warm-up's contraction) that map's fixed point; uneven probabilities give a
/// different image than uniform ones, and gradients still match finite differences.
#[test]
fn map_probabilities_choose_the_maps_and_keep_gradients_exact() {
    let cfg = config(
        Blend::Additive,
        1,
        SplatView::Window(Window {
            min: [-1.5, -1.5],
            max: [1.5, 1.5],
        }),
    );
    let maps = maps();
    let only_first = [1.0, 0.0, 0.0];
    let (_, tape) =
        splat::forward_with_probabilities::<f64>(&cfg, &maps, Some(&only_first), 7).unwrap();
    assert!(tape.trajectories.indices.iter().all(|&i| i == 0));
    let fixed = maps[0].fixed_point().unwrap();
    for p in tape.trajectories.kept_points() {
        assert!((p[0] - fixed[0]).abs() < 1e-2 && (p[1] - fixed[1]).abs() < 1e-2);
    }

    let uneven = [0.6, 0.3, 0.1];
    let (a, tape) =
        splat::forward_with_probabilities::<f64>(&cfg, &maps, Some(&uneven), 7).unwrap();
    let (b, _) = splat::forward::<f64>(&cfg, &maps, 7).unwrap();
    assert_ne!(a, b);
    let counts = (0..3)
        .map(|k| {
            tape.trajectories
                .indices
                .iter()
                .filter(|&&i| i == k)
                .count()
        })
        .collect::<Vec<_>>();
    assert!(counts[0] > 4 * counts[2], "{counts:?}");

    let w = weights(cfg.width * cfg.height);
    let grad = splat::backward(&cfg, &maps, &tape, &w).unwrap();
    let l = |m: &[Affine2]| -> f64 {
        let (img, _) = splat::forward_with_probabilities::<f64>(&cfg, m, Some(&uneven), 7).unwrap();
        img.iter().zip(&w).map(|(a, b)| a * b).sum()
    };
    for k in [0, 5, 9, 16] {
        let h = 1e-6;
        let mut mp = maps.clone();
        let mut mm = maps.clone();
        let mut cp = mp[k / 6].coefficients();
        let mut cm = mm[k / 6].coefficients();
        cp[k % 6] += h;
        cm[k % 6] -= h;
        mp[k / 6] = Affine2::from_coefficients(&cp);
        mm[k / 6] = Affine2::from_coefficients(&cm);
        let fd = (l(&mp) - l(&mm)) / (2.0 * h);
        assert!(
            (fd - grad[k]).abs() < 1e-5 * (1.0 + fd.abs()),
            "θ[{k}]: analytic {} vs fd {fd}",
            grad[k]
        );
    }
    let e = splat::forward_with_probabilities::<f64>(&cfg, &maps, Some(&[0.5, 0.5]), 7)
        .unwrap_err()
        .to_string();
    assert!(e.contains("2 probabilities for 3 maps"), "{e}");
}

/// `device = "cuda"` in a build without the GPU backend is refused with how to get one.
#[cfg(not(feature = "cuda"))]
#[test]
fn cuda_without_the_feature_is_refused_clearly() {
    use ifslab::render::splat::SplatDevice;
    let cfg = SplatConfig {
        device: SplatDevice::Cuda,
        ..config(Blend::Coverage, 1, SplatView::default())
    };
    let err = splat::forward::<f32>(&cfg, &maps(), 1)
        .unwrap_err()
        .to_string();
    assert!(err.contains("--features cuda"), "{err}");
    let parsed: SplatDevice = "cuda".parse().unwrap();
    assert_eq!(parsed, SplatDevice::Cuda);
    assert!("gpu".parse::<SplatDevice>().is_err());
}

/// The chaos game's and the backward scan's AVX2+FMA copies (an affine map's `mul_add`s one
/// instruction each) against the portable ones (calls to the runtime's `fma`): the same tape
/// and the same gradient, bit for bit — for affine maps, similitudes and flame transforms
/// with trigonometric variations.
#[test]
fn instruction_sets_give_the_same_tape_and_gradient() {
    use ifslab::isa::Isa;
    use ifslab::model::flame::{SmoothXform, Variation, VariationKind as V, Xform};
    use ifslab::model::{DiffMap2, Map, Similitude2};
    use ifslab::render::splat::trajectories::run_with_isa;

    fn both<M: DiffMap2>(maps: &[M], what: &str) {
        let game = ChaosGame {
            trajectories: 40,
            length: 90,
            warmup: 10,
            start_half_width: 1.5,
            seed: 0,
        };
        let run = |isa: Isa| {
            let tape = run_with_isa(&game, maps, None, 5, isa).unwrap();
            assert_eq!(tape.isa, isa);
            let g: Vec<[f64; 2]> = tape
                .kept_points()
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    [
                        (i as f64 * 0.37).sin() + p[0],
                        (i as f64 * 0.11).cos() - p[1],
                    ]
                })
                .collect();
            let grad = tape.backward(maps, &g);
            let states: Vec<[u64; 2]> = tape.states.iter().map(|p| p.map(f64::to_bits)).collect();
            let grad: Vec<u64> = grad.iter().map(|v| v.to_bits()).collect();
            (states, tape.indices, grad)
        };
        let portable = run(Isa::Portable);
        if !Isa::Fma.is_available() {
            assert!(run_with_isa(&game, maps, None, 5, Isa::Fma).is_err());
            return;
        }
        assert_eq!(portable, run(Isa::Fma), "{what}");
    }

    both(&maps(), "affine");
    both(
        &[
            Similitude2::new(0.5, 0.1, false, [-0.4, -0.3]),
            Similitude2::new(0.45, -0.2, true, [0.45, -0.2]),
            Similitude2::new(0.48, 0.05, false, [0.05, 0.5]),
        ],
        "similitudes",
    );
    let xform = |coefs: [f64; 6], kinds: &[(V, f64)]| {
        let vars = kinds.iter().map(|&(k, w)| Variation::new(k, w)).collect();
        SmoothXform::new(Xform::new(coefs, vars)).unwrap()
    };
    let flames = [
        xform(
            [0.5, 0.1, -0.05, 0.5, -0.4, -0.3],
            &[(V::Linear, 0.6), (V::Swirl, 0.3)],
        ),
        xform(
            [0.45, -0.12, 0.08, 0.42, 0.45, -0.2],
            &[(V::Handkerchief, 0.5)],
        ),
        xform(
            [0.4, 0.05, 0.1, 0.4, 0.05, 0.5],
            &[(V::Polar, 0.4), (V::Disc, 0.3)],
        ),
    ];
    assert!(
        flames
            .iter()
            .all(|f| f.apply([0.3, 0.2]).iter().all(|v| v.is_finite()))
    );
    both(&flames, "flame transforms");
}
