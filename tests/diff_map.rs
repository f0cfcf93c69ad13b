//! The differentiable maps the core ships ([`Affine2`], [`Similitude2`]): both
//! vector–Jacobian products against central finite differences in f64, the similitude's
//! affine-part chain rule likewise, and the splatter run on similitudes agreeing with the
//! same maps run as affine maps (image and gradient).

use candle_core::{DType, Device, Tensor, Var};
use ifslab::chaos::ChaosGame;
use ifslab::model::diff_map::{VjpCheck, flat_params, vjp_check};
use ifslab::model::{Affine2, AffinePart, DiffMap, Map, Similitude2};
use ifslab::render::splat::{self, Blend, SplatConfig, SplatOp, SplatView, params_to_tensor};
use proptest::prelude::*;

/// Both products agree with central differences to `tol` relative to the derivatives' size,
/// and the fused product equals the separate ones exactly.
fn assert_vjps(r: VjpCheck, tol: f64) -> Result<(), TestCaseError> {
    prop_assert!(
        r.point <= tol * (1.0 + r.scale),
        "point vjp off by {}",
        r.point
    );
    prop_assert!(
        r.params <= tol * (1.0 + r.scale),
        "parameter vjp off by {}",
        r.params
    );
    prop_assert!(r.fused == 0.0, "fused vjp differs by {}", r.fused);
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// `λᵀ(Mx + b)` is bilinear, so central differences are exact up to rounding:
    /// `∂/∂x = Mᵀλ`, `∂/∂M = λxᵀ`, `∂/∂b = λ`.
    #[test]
    fn affine_vjps_match_finite_differences(
        c in prop::collection::vec(-1.5f64..1.5, 6),
        x in prop::array::uniform2(-3.0f64..3.0),
        lam in prop::array::uniform2(-2.0f64..2.0),
    ) {
        assert_vjps(vjp_check(&Affine2::from_coefficients(&c), x, lam, 1e-5), 1e-8)?;
    }

    /// `∂f/∂s = R F x`, `∂f/∂φ = s R′ F x`, `∂f/∂t = I`, `∂f/∂x = s R F`; with and without
    /// the reflection, negative scales included.
    #[test]
    fn similitude_vjps_match_finite_differences(
        s in -1.2f64..1.2,
        angle in -4.0f64..4.0,
        reflect in any::<bool>(),
        t in prop::array::uniform2(-1.0f64..1.0),
        x in prop::array::uniform2(-3.0f64..3.0),
        lam in prop::array::uniform2(-2.0f64..2.0),
    ) {
        let map = Similitude2::new(s, angle, reflect, t);
        assert_vjps(vjp_check(&map, x, lam, 1e-6), 1e-7)?;
    }

    /// The regulariser's chain rule through `M = s·R(φ)·F`, `b = t`: for a fixed cotangent
    /// `(G, g)`, `∂/∂θ ⟨G, M(θ)⟩ + ⟨g, b(θ)⟩` equals `affine_part_backward(G, g)`.
    #[test]
    fn similitude_affine_part_chain_rule_matches_finite_differences(
        s in -1.2f64..1.2,
        angle in -4.0f64..4.0,
        reflect in any::<bool>(),
        g in prop::collection::vec(-2.0f64..2.0, 6),
    ) {
        let map = Similitude2::new(s, angle, reflect, [0.3, -0.4]);
        let cot = Affine2::from_coefficients(&g);
        let pair = |m: &Similitude2| {
            m.affine_part().coefficients().iter().zip(&g).map(|(a, b)| a * b).sum::<f64>()
        };
        let mut an = vec![0.0; 4];
        map.affine_part_backward(&cot, &mut an);
        let theta = map.params();
        let h = 1e-6;
        for k in 0..4 {
            let bumped = |d: f64| {
                let mut t = theta.clone();
                t[k] += d;
                let mut m = map;
                m.set_params(&t);
                m
            };
            let fd = (pair(&bumped(h)) - pair(&bumped(-h))) / (2.0 * h);
            prop_assert!((fd - an[k]).abs() <= 1e-7 * (1.0 + fd.abs()), "θ[{k}]: {} vs {fd}", an[k]);
        }
    }
}

/// The stated values: `M = [[1, 2], [3, 4]]`, `λ = (1, −1)`, `x = (2, 5)` gives
/// `Mᵀλ = (−2, −2)` and `λxᵀ = [[2, 5], [−2, −5]]`, `∂/∂b = λ`.
#[test]
fn affine_vjps_have_the_stated_values() {
    let m = Affine2::new(1.0, 2.0, 3.0, 4.0, 0.5, -0.5);
    let mut g = vec![0.0; 6];
    let gx = m.vjp([2.0, 5.0], [1.0, -1.0], &mut g);
    assert_eq!(gx, [-2.0, -2.0]);
    assert_eq!(g, vec![2.0, 5.0, -2.0, -5.0, 1.0, -1.0]);
    // Accumulates rather than overwrites.
    m.vjp_params([2.0, 5.0], [1.0, -1.0], &mut g);
    assert_eq!(g[0], 4.0);
}

fn config() -> SplatConfig {
    SplatConfig {
        width: 24,
        height: 20,
        supersample: 2,
        sigma: 1.3,
        radius: 3.0,
        blend: Blend::Coverage,
        alpha_max: 0.99,
        game: ChaosGame {
            trajectories: 20,
            length: 110,
            warmup: 10,
            start_half_width: 2.0,
            seed: 0,
        },
        framing: SplatView::default(),
        device: Default::default(),
    }
}

fn similitudes() -> Vec<Similitude2> {
    vec![
        Similitude2::new(0.5, 0.1, false, [-0.4, -0.3]),
        Similitude2::new(0.45, -0.2, true, [0.45, -0.2]),
        Similitude2::new(0.48, 0.05, false, [0.05, 0.5]),
    ]
}

/// The generic splatter on similitudes computes what the affine splatter computes on their
/// matrix forms: the same image, and a gradient that is the affine gradient pulled back
/// through `M = s·R·F`, `b = t` — also through the candle op with the flat layout.
#[test]
fn similitudes_splat_like_their_affine_forms() {
    let cfg = config();
    let sims = similitudes();
    let affine: Vec<Affine2> = sims.iter().map(Similitude2::to_affine).collect();
    let w: Vec<f64> = (0..cfg.width * cfg.height)
        .map(|i| ((i as f64 * 12.9898).sin() * 43758.5453).fract() - 0.25)
        .collect();
    let (img_s, tape_s) = splat::forward::<f64>(&cfg, &sims, 7).unwrap();
    let (img_a, tape_a) = splat::forward::<f64>(&cfg, &affine, 7).unwrap();
    assert!(
        img_a.iter().any(|&v| v > 0.05),
        "the render must not be empty"
    );
    for (a, b) in img_s.iter().zip(&img_a) {
        assert!((a - b).abs() < 1e-9, "{a} vs {b}");
    }
    let g_s = splat::backward(&cfg, &sims, &tape_s, &w).unwrap();
    let g_a = splat::backward(&cfg, &affine, &tape_a, &w).unwrap();
    assert_eq!((g_s.len(), g_a.len()), (12, 18));
    let mut pulled = vec![0.0; 12];
    for (i, m) in sims.iter().enumerate() {
        let ga = Affine2::from_coefficients(&g_a[i * 6..i * 6 + 6]);
        m.affine_part_backward(&ga, &mut pulled[i * 4..i * 4 + 4]);
    }
    let scale = pulled.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    assert!(scale > 1e-3, "gradients should not all vanish");
    for (a, b) in g_s.iter().zip(&pulled) {
        assert!((a - b).abs() < 1e-8 * (1.0 + scale), "{a} vs {b}");
    }

    // The candle op with the maps given: a flat (12,) argument, gradient of the same shape.
    let dev = Device::Cpu;
    let var = Var::from_tensor(&params_to_tensor(&sims, DType::F64, &dev).unwrap()).unwrap();
    assert_eq!(var.dims(), &[12]);
    let image = var
        .as_tensor()
        .apply_op1(SplatOp::with_maps(cfg.clone(), 7, sims.clone()))
        .unwrap();
    let got: Vec<f64> = image.flatten_all().unwrap().to_vec1().unwrap();
    assert_eq!(got, img_s);
    let wt = Tensor::from_vec(w, (cfg.height, cfg.width), &dev).unwrap();
    let grads = (image * wt).unwrap().sum_all().unwrap().backward().unwrap();
    let g: Vec<f64> = grads.get(var.as_tensor()).unwrap().to_vec1().unwrap();
    assert_eq!(g, g_s);

    // And with one prototype: a (3, 4) argument.
    let rows = Tensor::from_vec(flat_params(&sims), (3, 4), &dev).unwrap();
    let proto = Similitude2::new(1.0, 0.0, false, [0.0, 0.0]);
    let image = rows
        .apply_op1(SplatOp::uniform(cfg.clone(), 7, proto))
        .unwrap();
    // Without the reflection on map 1 the image differs: structure is not a parameter.
    let got: Vec<f64> = image.flatten_all().unwrap().to_vec1().unwrap();
    assert_ne!(got, img_s);
}

/// Wrong argument shapes and non-finite parameters are refused with a message, not a panic.
#[test]
fn the_op_refuses_bad_arguments() {
    let cfg = config();
    let dev = Device::Cpu;
    let sims = similitudes();
    let short = Tensor::from_vec(vec![0.5f64; 11], 11, &dev).unwrap();
    let e = short
        .apply_op1(SplatOp::with_maps(cfg.clone(), 7, sims.clone()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("expects the 12 parameters of its 3 maps"), "{e}");
    let proto = Similitude2::new(1.0, 0.0, false, [0.0, 0.0]);
    let wide = Tensor::from_vec(vec![0.5f64; 15], (3, 5), &dev).unwrap();
    let e = wide
        .apply_op1(SplatOp::uniform(cfg.clone(), 7, proto))
        .unwrap_err()
        .to_string();
    assert!(e.contains("shape (n, 4)"), "{e}");
    let mut p = flat_params(&sims);
    p[6] = f64::INFINITY;
    let e = Tensor::from_vec(p, 12, &dev)
        .unwrap()
        .apply_op1(SplatOp::with_maps(cfg.clone(), 7, sims.clone()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("map 1, parameter 2"), "{e}");
    // A tape replayed with other maps.
    let (_, tape) = splat::forward::<f64>(&cfg, &sims, 7).unwrap();
    let g = vec![0.0; cfg.width * cfg.height];
    let e = splat::backward(&cfg, &sims[..2], &tape, &g)
        .unwrap_err()
        .to_string();
    assert!(e.contains("recorded with 3 maps but 2 were given"), "{e}");
    // Map2 is still what forward-only code uses.
    let p = proto.apply([1.0, 2.0]);
    assert_eq!(p, [1.0, 2.0]);
}

/// An affine map that declares a wrong fixed parameter count: the backward scan must notice
/// that the declared stride does not match the maps' offsets and use the offsets.
#[derive(Clone, Copy, Debug)]
struct MisdeclaredAffine(Affine2);

impl Map<2> for MisdeclaredAffine {
    fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        self.0.apply(p)
    }
}

impl DiffMap<2> for MisdeclaredAffine {
    const PARAMS: Option<usize> = Some(4);

    fn n_params(&self) -> usize {
        6
    }
    fn write_params(&self, out: &mut [f64]) {
        self.0.write_params(out)
    }
    fn set_params(&mut self, p: &[f64]) {
        self.0.set_params(p)
    }
    fn vjp_point(&self, x: [f64; 2], lambda: [f64; 2]) -> [f64; 2] {
        self.0.vjp_point(x, lambda)
    }
    fn vjp_params(&self, x: [f64; 2], lambda: [f64; 2], grad: &mut [f64]) {
        self.0.vjp_params(x, lambda, grad)
    }
}

#[test]
fn a_misdeclared_parameter_count_falls_back_to_offsets() {
    let cfg = config();
    let affine: Vec<Affine2> = similitudes().iter().map(Similitude2::to_affine).collect();
    let wrapped: Vec<MisdeclaredAffine> = affine.iter().copied().map(MisdeclaredAffine).collect();
    let w: Vec<f64> = (0..cfg.width * cfg.height)
        .map(|i| (i % 13) as f64 / 13.0 - 0.4)
        .collect();
    let (_, tape) = splat::forward::<f64>(&cfg, &affine, 5).unwrap();
    let (_, tape_w) = splat::forward::<f64>(&cfg, &wrapped, 5).unwrap();
    let g = splat::backward(&cfg, &affine, &tape, &w).unwrap();
    let g_w = splat::backward(&cfg, &wrapped, &tape_w, &w).unwrap();
    assert!(g.iter().any(|v| v.abs() > 1e-3));
    assert_eq!(g, g_w);
}
