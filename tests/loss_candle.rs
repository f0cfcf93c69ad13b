//! The losses as candle ops: autograd through `apply_loss` gives exactly the hand-written
//! gradient, composes with other tensor ops, and the composite objective's tensor total and
//! breakdown agree with the plain functions.

use candle_core::{DType, Device, Tensor, Var};
use ifslab::loss::candle_ops::Downsample2x;
use ifslab::loss::msmse::downsample2x;
use ifslab::loss::{
    DSsim, ImageLoss, LossConfig, Moments, MsMse, Objective, Regulariser, apply_loss,
};
use ifslab::model::Affine2;

fn image(w: usize, h: usize, seed: usize) -> Vec<f64> {
    (0..w * h)
        .map(|i| (((i + seed) * 2_654_435_761usize) % 1000) as f64 / 1000.0)
        .collect()
}

fn grad_of(total: &Tensor, x: &Var) -> Vec<f64> {
    let grads = total.backward().unwrap();
    grads
        .get(x.as_tensor())
        .expect("gradient reaches the prediction")
        .to_dtype(DType::F64)
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1::<f64>()
        .unwrap()
}

/// Autograd through the op equals the plain gradient, in f64 and f32.
fn check_op<L: ImageLoss + Clone + 'static>(loss: L) {
    let (w, h) = (23, 19);
    let (p, t) = (image(w, h, 1), image(w, h, 7));
    let dev = Device::Cpu;
    // f64
    let x = Var::from_vec(p.clone(), (h, w), &dev).unwrap();
    let target = Tensor::from_vec(t.clone(), (h, w), &dev).unwrap();
    let out = apply_loss(loss.clone(), x.as_tensor(), &target).unwrap();
    assert_eq!(out.dims(), &[] as &[usize]);
    let (v, g) = loss.value_and_grad(&p, &t, w, h).unwrap();
    assert_eq!(out.to_scalar::<f64>().unwrap(), v);
    assert_eq!(grad_of(&out, &x), g, "{}: f64 autograd", loss.name());
    // f32
    let (p32, t32): (Vec<f32>, Vec<f32>) = (
        p.iter().map(|&v| v as f32).collect(),
        t.iter().map(|&v| v as f32).collect(),
    );
    let x = Var::from_vec(p32.clone(), (h, w), &dev).unwrap();
    let target = Tensor::from_vec(t32.clone(), (h, w), &dev).unwrap();
    let out = apply_loss(loss.clone(), x.as_tensor(), &target).unwrap();
    let (v, g) = loss.value_and_grad(&p32, &t32, w, h).unwrap();
    assert_eq!(out.to_scalar::<f32>().unwrap(), v);
    let g64: Vec<f64> = g.iter().map(|&v| v as f64).collect();
    assert_eq!(grad_of(&out, &x), g64, "{}: f32 autograd", loss.name());
}

#[test]
fn autograd_through_each_loss_equals_the_plain_gradient() {
    check_op(MsMse::default());
    check_op(DSsim::default());
    check_op(Moments::default());
}

#[test]
fn the_op_composes_with_tensor_ops() {
    // pred = 0.5·x + 0.25, L = 3·msmse(pred) ⇒ ∂L/∂x = 1.5·∂msmse/∂pred.
    let (w, h) = (16, 12);
    let dev = Device::Cpu;
    let x = Var::from_vec(image(w, h, 3), (1, h, w), &dev).unwrap();
    let t = image(w, h, 11);
    let target = Tensor::from_vec(t.clone(), (1, h, w), &dev).unwrap();
    let pred = x.as_tensor().affine(0.5, 0.25).unwrap();
    let total = (apply_loss(MsMse::default(), &pred, &target).unwrap() * 3.0).unwrap();
    let p: Vec<f64> = pred.flatten_all().unwrap().to_vec1().unwrap();
    let (_, g) = MsMse::default().value_and_grad(&p, &t, w, h).unwrap();
    let got = grad_of(&total, &x);
    for (a, b) in got.iter().zip(&g) {
        assert!((a - 1.5 * b).abs() < 1e-15);
    }
}

#[test]
fn constant_prediction_skips_the_gradient_but_keeps_the_value() {
    let (w, h) = (9, 8);
    let dev = Device::Cpu;
    let (p, t) = (image(w, h, 2), image(w, h, 5));
    let pt = Tensor::from_vec(p.clone(), (h, w), &dev).unwrap();
    let tt = Tensor::from_vec(t.clone(), (h, w), &dev).unwrap();
    let v = apply_loss(DSsim::default(), &pt, &tt)
        .unwrap()
        .to_scalar::<f64>()
        .unwrap();
    assert_eq!(v, DSsim::default().value(&p, &t, w, h).unwrap());
}

#[test]
fn apply_loss_refuses_mismatches_clearly() {
    let dev = Device::Cpu;
    let a = Tensor::zeros((4, 5), DType::F32, &dev).unwrap();
    let b = Tensor::zeros((5, 4), DType::F32, &dev).unwrap();
    let msg = apply_loss(MsMse::default(), &a, &b)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("differ in shape"), "{msg}");
    let c = Tensor::zeros((4, 5), DType::F64, &dev).unwrap();
    let msg = apply_loss(MsMse::default(), &a, &c)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("to_dtype"), "{msg}");
    // (C, H, W) images are channels; a batch of them is not an image.
    let d = Tensor::zeros((2, 2, 4, 5), DType::F32, &dev).unwrap();
    let msg = apply_loss(MsMse::default(), &d, &d)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("(C, H, W)"), "{msg}");
}

#[test]
fn downsample_op_matches_the_pyramid_and_its_adjoint() {
    // ∂/∂x Σ(D(x) ⊙ r) = Dᵀ r, checked against finite differences (D is linear: exact).
    let (w, h) = (7, 5);
    let dev = Device::Cpu;
    let xv = image(w, h, 4);
    let x = Var::from_vec(xv.clone(), (h, w), &dev).unwrap();
    let y = x.as_tensor().apply_op1(Downsample2x).unwrap();
    assert_eq!(y.dims(), &[3, 4]);
    assert_eq!(
        y.flatten_all().unwrap().to_vec1::<f64>().unwrap(),
        downsample2x(&xv, w, h).0
    );
    let r = Tensor::from_vec(image(4, 3, 9), (3, 4), &dev).unwrap();
    let g = grad_of(&(&y * &r).unwrap().sum_all().unwrap(), &x);
    let rv: Vec<f64> = r.flatten_all().unwrap().to_vec1().unwrap();
    let f = |v: &[f64]| -> f64 {
        downsample2x(v, w, h)
            .0
            .iter()
            .zip(&rv)
            .map(|(a, b)| a * b)
            .sum()
    };
    for i in 0..w * h {
        let mut q = xv.clone();
        q[i] += 0.5;
        let up = f(&q);
        q[i] -= 1.0;
        let fd = (up - f(&q)) / 1.0;
        assert!((g[i] - fd).abs() < 1e-12);
    }
}

fn no_lpips() -> LossConfig {
    LossConfig {
        lpips_weight: 0.0,
        ..Default::default()
    }
}

#[test]
fn objective_total_and_gradient_match_the_plain_terms() {
    // total = 10·msmse + dssim + 0.5·moments ⇒ the gradient is the same combination.
    let (w, h) = (24, 20);
    let dev = Device::Cpu;
    let (p, t) = (image(w, h, 1), image(w, h, 2));
    let cfg = LossConfig {
        moments_weight: 0.5,
        ..no_lpips()
    };
    let target = Tensor::from_vec(t.clone(), (h, w), &dev).unwrap();
    let obj = Objective::new(cfg, &target).unwrap();
    let x = Var::from_vec(p.clone(), (h, w), &dev).unwrap();
    let (total, b) = obj.image_loss(x.as_tensor()).unwrap();
    let (m, gm) = MsMse::default().value_and_grad(&p, &t, w, h).unwrap();
    let (s, gs) = DSsim::default().value_and_grad(&p, &t, w, h).unwrap();
    let (mo, gmo) = Moments::default().value_and_grad(&p, &t, w, h).unwrap();
    assert_eq!(
        (b.msmse, b.dssim, b.moments, b.lpips),
        (Some(m), Some(s), Some(mo), None)
    );
    let expected = 10.0 * m + s + 0.5 * mo;
    assert!((b.total - expected).abs() < 1e-12);
    assert!((total.to_scalar::<f64>().unwrap() - expected).abs() < 1e-12);
    let g = grad_of(&total, &x);
    for i in 0..w * h {
        let e = 10.0 * gm[i] + gs[i] + 0.5 * gmo[i];
        assert!((g[i] - e).abs() < 1e-14, "pixel {i}: {} vs {e}", g[i]);
    }
}

#[test]
fn objective_adds_the_regulariser_on_the_maps() {
    let (w, h) = (12, 12);
    let dev = Device::Cpu;
    let target = Tensor::from_vec(image(w, h, 1), (h, w), &dev).unwrap();
    let pred = Tensor::from_vec(image(w, h, 6), (h, w), &dev).unwrap();
    let obj = Objective::new(no_lpips(), &target).unwrap();
    let maps = [
        Affine2::new(0.5, 0.1, -0.2, 0.4, 0.3, -0.5),
        Affine2::new(0.3, 0.0, 0.0, 0.6, -0.2, 0.1),
    ];
    let e = obj.evaluate(&pred, &maps).unwrap();
    let (r, gr) = Regulariser::default().value_and_grad(&maps).unwrap();
    assert_eq!(e.breakdown.regulariser, Some(r));
    assert_eq!(e.map_grad, gr);
    let image_only = e.image_total.to_scalar::<f64>().unwrap();
    assert!((e.breakdown.total - image_only - r).abs() < 1e-12);
}

#[test]
fn objective_skips_missing_lpips_weights_unless_required() {
    let dev = Device::Cpu;
    let target = Tensor::zeros((40, 40), DType::F32, &dev).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nowhere.safetensors");
    let cfg = LossConfig {
        lpips_weights: Some(missing.clone()),
        ..Default::default()
    };
    let obj = Objective::new(cfg.clone(), &target).unwrap();
    assert!(!obj.lpips_active());
    let reason = obj.lpips_skip_reason().unwrap();
    assert!(
        reason.contains("ifslab weights fetch") && reason.contains("nowhere.safetensors"),
        "{reason}"
    );
    let (_, b) = obj.image_loss(&target).unwrap();
    assert_eq!(b.lpips, None);
    let required = LossConfig {
        lpips_required: true,
        ..cfg
    };
    let msg = Objective::new(required, &target).unwrap_err().to_string();
    assert!(
        msg.contains("not found") && msg.contains("ifslab weights fetch"),
        "{msg}"
    );
}

#[test]
fn objective_refuses_a_bad_config_or_prediction() {
    let dev = Device::Cpu;
    let target = Tensor::zeros((8, 8), DType::F64, &dev).unwrap();
    let bad = LossConfig {
        dssim_weight: -0.5,
        ..no_lpips()
    };
    let msg = Objective::new(bad, &target).unwrap_err().to_string();
    assert!(msg.contains("dssim_weight must be ≥ 0, got -0.5"), "{msg}");
    let obj = Objective::new(no_lpips(), &target).unwrap();
    let wrong = Tensor::zeros((8, 9), DType::F64, &dev).unwrap();
    assert!(obj.image_loss(&wrong).is_err());
    // An f32 prediction against an f64 target works: the target is converted.
    let p32 = Tensor::ones((8, 8), DType::F32, &dev).unwrap();
    let (t, _) = obj.image_loss(&p32).unwrap();
    assert_eq!(t.dtype(), DType::F32);
}

#[test]
fn a_second_backward_pass_recomputes_the_same_gradient() {
    // The forward pass hands its gradient to the first backward; later ones recompute it.
    let (w, h) = (15, 11);
    let dev = Device::Cpu;
    let x = Var::from_vec(image(w, h, 8), (h, w), &dev).unwrap();
    let target = Tensor::from_vec(image(w, h, 9), (h, w), &dev).unwrap();
    let total = apply_loss(DSsim::default(), x.as_tensor(), &target).unwrap();
    let first = grad_of(&total, &x);
    let second = grad_of(&total, &x);
    assert_eq!(first, second);
}

// ------------------------------------------------------------------ multi-channel images

/// A `(3, H, W)` image is scored channel by channel: value = mean of the per-channel values,
/// gradient = per-channel gradient / 3 — checked against the plain function on each plane.
fn check_rgb<L: ImageLoss + Clone + 'static>(loss: L) {
    let (w, h) = (21, 17);
    let dev = Device::Cpu;
    let (pred, target): (Vec<f64>, Vec<f64>) = (
        (0..3).flat_map(|c| image(w, h, 3 + 11 * c)).collect(),
        (0..3).flat_map(|c| image(w, h, 5 + 13 * c)).collect(),
    );
    let x = Var::from_vec(pred.clone(), (3, h, w), &dev).unwrap();
    let t = Tensor::from_vec(target.clone(), (3, h, w), &dev).unwrap();
    let out = apply_loss(loss.clone(), x.as_tensor(), &t).unwrap();
    let n = w * h;
    let (mut value, mut grad) = (0.0, Vec::new());
    for c in 0..3 {
        let (v, g) = loss
            .value_and_grad(&pred[c * n..(c + 1) * n], &target[c * n..(c + 1) * n], w, h)
            .unwrap();
        value += v / 3.0;
        grad.extend(g.iter().map(|g| g / 3.0));
    }
    let got = out.to_scalar::<f64>().unwrap();
    assert!(
        (got - value).abs() <= 1e-12 * value.abs().max(1e-12),
        "{}: {got} vs {value}",
        loss.name()
    );
    let g = grad_of(&out, &x);
    for (i, (a, b)) in g.iter().zip(&grad).enumerate() {
        assert!(
            (a - b).abs() <= 1e-12 * b.abs().max(1e-9),
            "{}: ∂/∂x[{i}] {a} vs {b}",
            loss.name()
        );
    }
    // And the channels really are separate: central differences in each plane.
    let f = |v: &[f64]| {
        let p = Tensor::from_vec(v.to_vec(), (3, h, w), &dev).unwrap();
        apply_loss(loss.clone(), &p, &t)
            .unwrap()
            .to_scalar::<f64>()
            .unwrap()
    };
    for &i in &[5, n + 40, 2 * n + 200] {
        let e = 1e-6;
        let mut v = pred.clone();
        v[i] += e;
        let up = f(&v);
        v[i] -= 2.0 * e;
        let fd = (up - f(&v)) / (2.0 * e);
        assert!(
            (fd - g[i]).abs() <= 1e-6 + 1e-4 * fd.abs(),
            "{}: pixel {i}: fd {fd} vs {}",
            loss.name(),
            g[i]
        );
    }
}

#[test]
fn losses_on_rgb_images_are_the_mean_over_channels() {
    check_rgb(MsMse::new(3));
    check_rgb(DSsim::default());
    check_rgb(Moments::default());
}

#[test]
fn downsampling_an_rgb_image_downsamples_each_plane() {
    let (w, h) = (9, 7);
    let dev = Device::Cpu;
    let v: Vec<f64> = (0..3).flat_map(|c| image(w, h, 2 + c)).collect();
    let x = Var::from_vec(v.clone(), (3, h, w), &dev).unwrap();
    let d = x.as_tensor().apply_op1(Downsample2x).unwrap();
    assert_eq!(d.dims(), &[3, 4, 5]);
    let got = d.flatten_all().unwrap().to_vec1::<f64>().unwrap();
    let want: Vec<f64> = v
        .chunks_exact(w * h)
        .flat_map(|p| downsample2x(p, w, h).0)
        .collect();
    assert_eq!(got, want);
    // Its reverse pass is the adjoint: ⟨D x, y⟩ = ⟨x, Dᵀ y⟩ for y = ones.
    let g = grad_of(&d.sum_all().unwrap(), &x);
    let lhs: f64 = got.iter().sum();
    let rhs: f64 = g.iter().zip(&v).map(|(a, b)| a * b).sum();
    assert!((lhs - rhs).abs() < 1e-12, "{lhs} vs {rhs}");
}

#[test]
fn objective_on_an_rgb_target_with_grey_channels_equals_the_grey_objective() {
    let (w, h) = (24, 20);
    let dev = Device::Cpu;
    let (p, t) = (image(w, h, 1), image(w, h, 9));
    let grey = |v: &[f64]| Tensor::from_vec(v.to_vec(), (h, w), &dev).unwrap();
    let rgb = |v: &[f64]| Tensor::from_vec(v.repeat(3), (3, h, w), &dev).unwrap();
    let cfg = LossConfig {
        moments_weight: 0.5,
        ..no_lpips()
    };
    let a = Objective::new(cfg.clone(), &grey(&t)).unwrap();
    let b = Objective::new(cfg, &rgb(&t)).unwrap();
    let (va, _) = a.image_loss(&grey(&p)).unwrap();
    let (vb, _) = b.image_loss(&rgb(&p)).unwrap();
    let (va, vb) = (
        va.to_scalar::<f64>().unwrap(),
        vb.to_scalar::<f64>().unwrap(),
    );
    assert!((va - vb).abs() < 1e-12 * va.abs(), "{va} vs {vb}");
    // A 3-channel prediction against a grey target is a shape error, not a broadcast.
    let e = a.image_loss(&rgb(&p)).unwrap_err();
    assert!(e.to_string().contains("differ in shape"), "{e}");
    // LPIPS needs grey or RGB.
    let four = Tensor::from_vec(t.repeat(4), (4, h, w), &dev).unwrap();
    let e = Objective::new(
        LossConfig {
            lpips_weight: 1.0,
            ..LossConfig::default()
        },
        &four,
    )
    .unwrap_err();
    assert!(e.to_string().contains("4 channels"), "{e}");
}
