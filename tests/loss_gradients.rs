//! Every loss's hand-written gradient against central finite differences, in f64, on small
//! images of even and odd sizes (proptest over random images), and the regulariser's
//! gradient through both parameterisations.

use ifslab::loss::{ConditionTerm, DSsim, ImageLoss, Moments, MsMse, MsMseReduction, Regulariser};
use ifslab::model::param::{Naive, Parameterisation, Svd};
use proptest::prelude::*;

/// Central differences `(L(x + h·e_i) − L(x − h·e_i)) / 2h` at the pixels `idx`.
fn fd_grad<L: ImageLoss>(
    loss: &L,
    p: &[f64],
    t: &[f64],
    w: usize,
    h: usize,
    idx: &[usize],
) -> Vec<f64> {
    let step = 1e-5;
    idx.iter()
        .map(|&i| {
            let mut q = p.to_vec();
            q[i] = p[i] + step;
            let up = loss.value(&q, t, w, h).unwrap();
            q[i] = p[i] - step;
            let down = loss.value(&q, t, w, h).unwrap();
            (up - down) / (2.0 * step)
        })
        .collect()
}

/// Checks ∂L/∂pred against finite differences at every pixel (small images) or at a spread
/// of pixels including the four corners (larger ones).
fn check_loss<L: ImageLoss>(
    loss: &L,
    p: &[f64],
    t: &[f64],
    w: usize,
    h: usize,
) -> Result<(), TestCaseError> {
    let (value, grad) = loss.value_and_grad(p, t, w, h).unwrap();
    prop_assert!(value.is_finite());
    prop_assert_eq!(grad.len(), w * h);
    let idx: Vec<usize> = if w * h <= 200 {
        (0..w * h).collect()
    } else {
        let mut v: Vec<usize> = (0..w * h).step_by(7).collect();
        v.extend([0, w - 1, (h - 1) * w, w * h - 1]);
        v
    };
    let fd = fd_grad(loss, p, t, w, h, &idx);
    let scale = grad.iter().fold(0.0f64, |m, g| m.max(g.abs()));
    for (&i, &g_fd) in idx.iter().zip(&fd) {
        let err = (grad[i] - g_fd).abs();
        prop_assert!(
            err <= 1e-6 * scale + 1e-10,
            "{}: pixel {i} ({}, {}) of {w}×{h}: analytic {} vs finite difference {g_fd} (max |g| {scale})",
            loss.name(),
            i % w,
            i / w,
            grad[i]
        );
    }
    Ok(())
}

fn image_pair() -> impl Strategy<Value = (usize, usize, Vec<f64>, Vec<f64>)> {
    prop_oneof![
        Just((24usize, 20usize)),
        Just((13, 9)),
        Just((7, 11)),
        (2usize..16, 2usize..16)
    ]
    .prop_flat_map(|(w, h)| {
        (
            Just(w),
            Just(h),
            prop::collection::vec(0.0f64..1.0, w * h),
            prop::collection::vec(0.0f64..1.0, w * h),
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    /// ∂/∂P Σ_l w_l·mean((P_l − T_l)²), pulled back through the 2×2 pooling.
    #[test]
    fn msmse_gradient_matches_finite_differences((w, h, p, t) in image_pair()) {
        check_loss(&MsMse::default(), &p, &t, w, h)?;
        check_loss(&MsMse::new(2).with_reduction(MsMseReduction::Mean), &p, &t, w, h)?;
    }

    /// ∂(1 − SSIM)/∂P with the zero-padded 11-px Gaussian window.
    #[test]
    fn dssim_gradient_matches_finite_differences((w, h, p, t) in image_pair()) {
        check_loss(&DSsim::default(), &p, &t, w, h)?;
    }

    /// ∂/∂P of the squared differences of centroid, variance, skewness and kurtosis.
    #[test]
    fn moments_gradient_matches_finite_differences((w, h, p, t) in image_pair()) {
        check_loss(&Moments::default(), &p, &t, w, h)?;
        check_loss(&Moments { max_order: 6 }, &p, &t, w, h)?;
    }

    /// R(decode(θ)) differentiated by Regulariser::value_and_grad then Naive::backward.
    #[test]
    fn regulariser_gradient_through_naive(theta in (1usize..=4)
        .prop_flat_map(|n| prop::collection::vec(-0.9f64..0.9, 6 * n))) {
        check_regulariser(&Naive, &theta)?;
    }

    /// The same through the SVD parameterisation (Gram–Schmidt, sigmoid, tanh).
    #[test]
    fn regulariser_gradient_through_svd(theta in (1usize..=3)
        .prop_flat_map(|n| prop::collection::vec(-2.0f64..2.0, 12 * n))) {
        check_regulariser(&Svd::default(), &theta)?;
    }
}

fn check_regulariser(param: &dyn Parameterisation, theta: &[f64]) -> Result<(), TestCaseError> {
    for condition in [ConditionTerm::Paper, ConditionTerm::Reference] {
        let reg = Regulariser {
            condition,
            ..Regulariser::default()
        };
        check_regulariser_form(&reg, param, theta)?;
    }
    Ok(())
}

fn check_regulariser_form(
    reg: &Regulariser,
    param: &dyn Parameterisation,
    theta: &[f64],
) -> Result<(), TestCaseError> {
    let f = |th: &[f64]| reg.value(&param.decode(th).unwrap()).unwrap();
    let maps = param.decode(theta).unwrap();
    let (_, grad_maps) = reg.value_and_grad(&maps).unwrap();
    let grad = param.backward(theta, &grad_maps).unwrap();
    let step = 1e-6;
    for i in 0..theta.len() {
        let mut th = theta.to_vec();
        th[i] += step;
        let up = f(&th);
        th[i] -= 2.0 * step;
        let down = f(&th);
        let fd = (up - down) / (2.0 * step);
        prop_assert!(
            (grad[i] - fd).abs() <= 1e-6 * (1.0 + fd.abs()),
            "{} ({:?}): θ[{i}] analytic {} vs finite difference {fd}",
            param.name(),
            reg.condition,
            grad[i]
        );
    }
    Ok(())
}

#[test]
fn msmse_gradient_on_a_single_row_and_column() {
    // Degenerate shapes: the pyramid stops at once, MS-MSE is the plain MSE.
    let p = [0.1, 0.7, 0.3, 0.9, 0.4];
    let t = [0.0, 0.5, 0.5, 1.0, 0.2];
    for (w, h) in [(5, 1), (1, 5)] {
        check_loss(&MsMse::default(), &p, &t, w, h).unwrap();
        let (v, _) = MsMse::default().value_and_grad(&p, &t, w, h).unwrap();
        let mse: f64 = p
            .iter()
            .zip(&t)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            / 5.0;
        assert!((v - mse).abs() < 1e-15);
    }
}

#[test]
fn dssim_gradient_on_sparse_fractal_like_images() {
    // Mostly-black images with a few bright pixels, like a chaos-game render.
    let (w, h) = (21, 17);
    let mut p = vec![0.0; w * h];
    let mut t = vec![0.0; w * h];
    for i in 0..w * h {
        if (i * 7919) % 11 == 0 {
            p[i] = 0.9;
        }
        if (i * 104_729) % 13 == 0 {
            t[i] = 1.0;
        }
    }
    check_loss(&DSsim::default(), &p, &t, w, h).unwrap();
    check_loss(&MsMse::default(), &p, &t, w, h).unwrap();
}

#[test]
fn regulariser_gradient_near_degenerate_maps_stays_bounded() {
    // σ₁ − σ₂ = 1e-9: gradients stay finite and of the order of the weights.
    let map = ifslab::model::Affine2::new(0.5 + 1e-9, 0.0, 0.0, 0.5, 0.1, 0.2);
    let (_, g) = Regulariser::default().value_and_grad(&[map]).unwrap();
    assert!(g[0].is_finite());
    assert!(g[0].m.norm() < 1.0, "{}", g[0].m);
}
