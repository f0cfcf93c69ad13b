//! Every deterministic variation's derivatives, through a whole transform (pre-affine,
//! two weighted variations, post-affine), against central finite differences.
//!
//! For f(p; θ) = post(Σ wᵢ·Vᵢ(pre(p))), `jacobian` must equal (f(p + h·eₖ) − f(p − h·eₖ))/2h
//! and `vjp_params` must equal gᵀ·(f(θ + h·eⱼ) − f(θ − h·eⱼ))/2h for every θⱼ (pre-affine
//! coefficients, variation weights and parameters, post-affine coefficients). Several
//! variations have jumps (floor, fmod, branches on the angle or radius); near one the finite
//! difference is meaningless, which shows as a difference quotient that changes with the
//! step. Such cases are discarded (`prop_assume!`), so they count against proptest's limit
//! on rejections: a derivative that is wrong everywhere cannot hide behind them.

use ifslab::model::Map;
use ifslab::model::flame::{SmoothXform, Variation, VariationKind, Xform};
use proptest::prelude::*;

fn deterministic() -> Vec<VariationKind> {
    VariationKind::ALL
        .into_iter()
        .filter(|k| !k.is_random())
        .collect()
}

fn build(
    kinds: [VariationKind; 2],
    weights: [f64; 2],
    offsets: &[f64],
    coefs: [f64; 6],
    post: [f64; 6],
) -> Xform {
    let mut vars = Vec::new();
    for (i, (&k, &w)) in kinds.iter().zip(&weights).enumerate() {
        if i == 1 && kinds[1] == kinds[0] {
            break;
        }
        let mut v = Variation::new(k, w);
        for (j, (name, default)) in k.params().iter().enumerate() {
            v.set_param(name, default + offsets[(8 * i + j) % offsets.len()])
                .unwrap();
        }
        vars.push(v);
    }
    let mut x = Xform::new(coefs, vars);
    x.post = post;
    x
}

fn eval(x: &Xform, p: [f64; 2]) -> [f64; 2] {
    SmoothXform::new(x.clone()).unwrap().apply(p)
}

/// Central difference of `f` at steps `h`, `h/4` and `h/16`; `None` when they disagree (a
/// jump or a singularity within reach) or are not finite. Three steps, because a jump on
/// each side can cancel into a plausible quotient for two of them. The one-sided
/// differences at the smallest step must agree with each other too: where a parameter moves
/// a branch many times within the step (fan2's period shrinks like fan2_x², so a change of
/// 1e-6 in fan2_x crosses several of its angular sectors), both ends of every central
/// difference can land on the *other* branch and agree with each other perfectly, while the
/// centre, which the analytic derivative describes, sits on a third. Only a difference that
/// includes the centre sees that.
fn stable_diff(f: impl Fn(f64) -> [f64; 2], h: f64) -> Option<[f64; 2]> {
    let d = |h: f64| {
        let (a, b) = (f(h), f(-h));
        [(a[0] - b[0]) / (2.0 * h), (a[1] - b[1]) / (2.0 * h)]
    };
    let ds = [d(h), d(h / 4.0), d(h / 16.0)];
    let (c, a, b) = (f(0.0), f(h / 16.0), f(-h / 16.0));
    for k in 0..2 {
        for pair in ds.windows(2) {
            let (a, b) = (pair[0][k], pair[1][k]);
            if !(a.is_finite() && b.is_finite()) || (a - b).abs() > 1e-5 * (1.0 + b.abs()) {
                return None;
            }
        }
        // First-order quotients: their error is h/16·|f''|, so the bound is loose; a jump
        // of any visible size divided by h/16 is far outside it.
        let forward = (a[k] - c[k]) / (h / 16.0);
        let backward = (c[k] - b[k]) / (h / 16.0);
        if !(forward - backward).is_finite()
            || (forward - backward).abs() > 1e-2 * (1.0 + ds[2][k].abs())
        {
            return None;
        }
    }
    // Richardson extrapolation of the two larger steps: truncation error O(h⁴), and the
    // rounding error of a step of h/4 rather than h/16 (it matters where f is large).
    Some([
        (16.0 * ds[1][0] - ds[0][0]) / 15.0,
        (16.0 * ds[1][1] - ds[0][1]) / 15.0,
    ])
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-5 * (1.0 + a.abs().max(b.abs()))
}

/// A number in ±[min, max]. Coefficients and parameter offsets stay this far from zero
/// because several variations turn one of them into a period (rings: the pre-affine
/// translation e², fan: e²·π, fan2: fan2_x²·π, rings2: rings2_val²): near zero the sawtooth
/// is narrower than any usable difference step, so no finite difference can check the
/// (correct, but only locally meaningful) derivative inside one tooth.
fn signed(min: f64, max: f64) -> impl Strategy<Value = f64> {
    (min..max, any::<bool>()).prop_map(|(v, neg)| if neg { -v } else { v })
}

fn coefs() -> impl Strategy<Value = [f64; 6]> {
    prop::array::uniform6(signed(0.02, 1.0))
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 3000,
        max_global_rejects: 3000,
        ..ProptestConfig::default()
    })]

    /// ∂f/∂p of the transform is the finite-difference Jacobian, and `vjp_point` is gᵀ·J.
    #[test]
    fn point_jacobian_matches_finite_differences(
        k0 in 0usize..1000, k1 in 0usize..1000,
        weights in prop::array::uniform2(0.2f64..1.2),
        offsets in prop::collection::vec(signed(0.02, 0.4), 16),
        pre in coefs(), post in coefs(),
        p in prop::array::uniform2(-1.5f64..1.5),
        g in prop::array::uniform2(-1.0f64..1.0),
    ) {
        let det = deterministic();
        let kinds = [det[k0 % det.len()], det[k1 % det.len()]];
        let x = build(kinds, weights, &offsets, pre, post);
        let y = eval(&x, p);
        prop_assume!(y[0].is_finite() && y[1].is_finite() && y[0].abs() < 1e6 && y[1].abs() < 1e6);
        let j = x.jacobian(p).unwrap();
        let mut cols = [[0.0; 2]; 2];
        for c in 0..2 {
            let d = stable_diff(
                |h| {
                    let mut q = p;
                    q[c] += h;
                    eval(&x, q)
                },
                1e-6,
            );
            prop_assume!(d.is_some());
            cols[c] = d.unwrap();
        }
        for r in 0..2 {
            for c in 0..2 {
                prop_assert!(
                    close(j[r][c], cols[c][r]),
                    "{:?}: ∂f{r}/∂p{c} = {} analytic, {} finite difference at {p:?}",
                    kinds, j[r][c], cols[c][r]
                );
            }
        }
        let v = x.vjp_point(p, g).unwrap();
        for c in 0..2 {
            prop_assert!(close(v[c], g[0] * j[0][c] + g[1] * j[1][c]));
        }
    }

    /// gᵀ·∂f/∂θ for every parameter θⱼ is the finite difference of gᵀ·f, and `vjp_params`
    /// adds to what `grad` held.
    #[test]
    fn parameter_gradient_matches_finite_differences(
        k0 in 0usize..1000, k1 in 0usize..1000,
        weights in prop::array::uniform2(0.2f64..1.2),
        offsets in prop::collection::vec(signed(0.02, 0.4), 16),
        pre in coefs(), post in coefs(),
        p in prop::array::uniform2(-1.5f64..1.5),
        g in prop::array::uniform2(-1.0f64..1.0),
    ) {
        let det = deterministic();
        let kinds = [det[k0 % det.len()], det[k1 % det.len()]];
        let x = build(kinds, weights, &offsets, pre, post);
        let y = eval(&x, p);
        prop_assume!(y[0].is_finite() && y[1].is_finite() && y[0].abs() < 1e6 && y[1].abs() < 1e6);
        let theta = x.params();
        let n = x.n_params();
        prop_assert_eq!(theta.len(), n);
        let mut grad = vec![1.0; n];
        x.vjp_params(p, g, &mut grad).unwrap();
        for (i, gi) in grad.iter_mut().enumerate() {
            *gi -= 1.0;
            let d = stable_diff(
                |h| {
                    let mut t = theta.clone();
                    t[i] += h;
                    let mut xi = x.clone();
                    xi.set_params(&t).unwrap();
                    eval(&xi, p)
                },
                1e-6,
            );
            prop_assume!(d.is_some());
            let d = d.unwrap();
            let fd = g[0] * d[0] + g[1] * d[1];
            prop_assert!(
                close(*gi, fd),
                "{:?}: gᵀ∂f/∂θ{i} = {} analytic, {} finite difference at {p:?}",
                kinds, gi, fd
            );
        }
    }
}

#[test]
fn random_variations_have_no_jacobian() {
    let x = Xform::new(
        [1.0, 0.0, 0.0, 1.0, 0.0, 0.0],
        vec![Variation::new(VariationKind::Blur, 1.0)],
    );
    let e = x.jacobian([0.1, 0.2]).unwrap_err().to_string();
    assert!(e.contains("blur"), "{e}");
    assert!(SmoothXform::new(x).is_err());
}

/// The case that slipped through the central differences alone: fan2 with fan2_x = 0.0069
/// (an angular period of 1.5e-4), where every step of 1e-6, 2.5e-7 and 6.25e-8 in fan2_x
/// lands on the other branch of the sector test. It must be recognised as a jump.
#[test]
fn a_parameter_that_moves_a_branch_many_times_within_the_step_is_not_differenced() {
    let mut fan2 = Variation::new(VariationKind::Fan2, 0.2);
    fan2.set_param("fan2_x", 0.006894981734184817).unwrap();
    fan2.set_param("fan2_y", 0.09745502783947532).unwrap();
    let mut x = Xform::new(
        [
            -0.2142889, 0.0127450, 0.9302360, -0.9402044, 0.2687353, -0.6283819,
        ],
        vec![Variation::new(VariationKind::Linear, 0.2), fan2],
    );
    x.post = [0.0, 0.0, 0.0, 0.24119330363015967, 0.0, 0.0];
    let p = [-0.9538377634828817, -0.35225103522402357];
    let theta = x.params();
    // θ₈ is fan2_x: pre (6), linear's weight, fan2's weight, then its parameters.
    let d = stable_diff(
        |h| {
            let mut t = theta.clone();
            t[8] += h;
            let mut xi = x.clone();
            xi.set_params(&t).unwrap();
            eval(&xi, p)
        },
        1e-6,
    );
    assert!(d.is_none(), "{d:?}");
}
