//! LPIPS through candle: clear errors for missing or broken weight files, and — with the real
//! weights (`ifslab weights fetch`; `scripts/test.sh` fetches them, and these tests fail
//! without them rather than pass unchecked) — agreement with the numpy reference in
//! tests/fixtures/loss_lpips_reference.json, the identity and ordering properties, and the
//! autograd gradient against finite differences.

use std::collections::HashMap;
use std::sync::OnceLock;

use candle_core::{DType, Device, Tensor, Var};
use ifslab::Error;
use ifslab::loss::lpips::{LPIPS_WEIGHTS_ENV, expected_tensors};
use ifslab::loss::{LossConfig, Lpips, Objective, default_lpips_weights_path};

// ------------------------------------------------------------------ always-run error tests

fn weights_error(path: &std::path::Path) -> String {
    match Lpips::load(path) {
        Err(e @ Error::Weights { .. }) => e.to_string(),
        Err(e) => panic!("expected a weights error, got {e}"),
        Ok(_) => panic!("loading {} should fail", path.display()),
    }
}

#[test]
fn missing_file_says_how_to_fetch_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lpips_alexnet.safetensors");
    let msg = weights_error(&path);
    assert!(msg.contains("not found"), "{msg}");
    assert!(msg.contains("ifslab weights fetch"), "{msg}");
    assert!(msg.contains(LPIPS_WEIGHTS_ENV), "{msg}");
    assert!(msg.contains(&path.display().to_string()), "{msg}");
}

#[test]
fn corrupt_file_is_reported_as_such() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.safetensors");
    std::fs::write(&path, b"\x10\x00\x00\x00\x00\x00\x00\x00{not json at all").unwrap();
    let msg = weights_error(&path);
    assert!(msg.contains("cannot be read as safetensors"), "{msg}");
    assert!(msg.contains("ifslab weights fetch"), "{msg}");
}

#[test]
fn wrong_or_missing_tensors_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let dev = Device::Cpu;
    // A file without the first tensor.
    let path = dir.path().join("other.safetensors");
    let mut m = HashMap::new();
    m.insert(
        "unrelated".to_string(),
        Tensor::zeros(3, DType::F32, &dev).unwrap(),
    );
    candle_core::safetensors::save(&m, &path).unwrap();
    let msg = weights_error(&path);
    assert!(
        msg.contains("has no tensor `conv1.weight`") && msg.contains("[64, 3, 11, 11]"),
        "{msg}"
    );
    // A file whose conv1 kernel has the wrong shape.
    let path = dir.path().join("shape.safetensors");
    let mut m = HashMap::new();
    m.insert(
        "conv1.weight".to_string(),
        Tensor::zeros((64, 3, 5, 5), DType::F32, &dev).unwrap(),
    );
    candle_core::safetensors::save(&m, &path).unwrap();
    let msg = weights_error(&path);
    assert!(
        msg.contains("`conv1.weight` has shape [64, 3, 5, 5], expected [64, 3, 11, 11]"),
        "{msg}"
    );
    // A complete file of the right shapes but a negative head weight.
    let path = dir.path().join("negative.safetensors");
    let mut m = HashMap::new();
    for (name, shape) in expected_tensors() {
        let fill = if name == "lin2.weight" { -1.0 } else { 0.01 };
        m.insert(
            name,
            (Tensor::ones(shape, DType::F32, &dev).unwrap() * fill).unwrap(),
        );
    }
    candle_core::safetensors::save(&m, &path).unwrap();
    let msg = weights_error(&path);
    assert!(msg.contains("`lin2.weight` has negative weights"), "{msg}");
}

// ------------------------------------------------------------------ tests with real weights

/// The real network. Its tests need the weights file: `scripts/test.sh` (what CI runs)
/// fetches it first, so a missing file fails here instead of passing silently.
fn net() -> &'static Lpips {
    static NET: OnceLock<Lpips> = OnceLock::new();
    NET.get_or_init(|| {
        Lpips::try_load_default()
            .expect("the LPIPS weights file exists but does not load")
            .unwrap_or_else(|| {
                panic!(
                    "no LPIPS weights at {}: run `ifslab weights fetch` (scripts/test.sh does) \
                     or point IFSLAB_LPIPS_WEIGHTS at a copy",
                    default_lpips_weights_path().display()
                )
            })
    })
}

/// The procedural images of scripts/fetch_lpips.py (`procedural_image`), bit for bit.
fn procedural(kind: &str, w: usize, h: usize) -> Vec<f32> {
    let mut img = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let (xf, yf, wf, hf) = (x as f64, y as f64, w as f64, h as f64);
            let v = match kind {
                "waves" => {
                    0.5 + 0.25 * (0.31 * xf + 0.17 * yf).sin()
                        + 0.2 * (0.23 * yf - 0.05 * xf * xf / wf).cos()
                }
                "waves_shifted" => {
                    0.5 + 0.25 * (0.31 * xf + 0.17 * yf + 0.6).sin()
                        + 0.2 * (0.23 * yf - 0.05 * xf * xf / wf).cos()
                }
                "disc" => {
                    let (cx, cy, r) = (0.45 * wf, 0.55 * hf, 0.3 * wf.min(hf));
                    let d = (xf + 0.5 - cx).hypot(yf + 0.5 - cy);
                    1.0 / (1.0 + ((d - r) / 1.5).exp())
                }
                "noise" => {
                    let (xu, yu) = (x as u64, y as u64);
                    let hh = ((xu * 73_856_093) ^ (yu * 19_349_663) ^ 0x5BD1_E995) & 0xFFFF_FFFF;
                    let hh = (hh * 2_654_435_761) & 0xFFFF_FFFF;
                    ((hh >> 8) & 0xFFFF) as f64 / 65535.0
                }
                _ => unreachable!("unknown image {kind}"),
            };
            img.push(v.clamp(0.0, 1.0) as f32);
        }
    }
    img
}

fn tensor(img: &[f32], w: usize, h: usize) -> Tensor {
    Tensor::from_slice(img, (h, w), &Device::Cpu).unwrap()
}

fn scalar(t: &Tensor) -> f64 {
    t.to_dtype(DType::F64).unwrap().to_scalar::<f64>().unwrap()
}

#[test]
fn agrees_with_the_numpy_reference() {
    let net = net();
    let fixture: serde_json::Value =
        serde_json::from_str(include_str!("fixtures/loss_lpips_reference.json")).unwrap();
    let w = fixture["width"].as_u64().unwrap() as usize;
    let h = fixture["height"].as_u64().unwrap() as usize;
    for case in fixture["cases"].as_array().unwrap() {
        let (a, b) = (
            case["pred"].as_str().unwrap(),
            case["target"].as_str().unwrap(),
        );
        let (p, t) = (
            tensor(&procedural(a, w, h), w, h),
            tensor(&procedural(b, w, h), w, h),
        );
        let got = scalar(&net.distance(&p, &t).unwrap());
        let want = case["lpips"].as_f64().unwrap();
        eprintln!("LPIPS({a}, {b}): ours (f32) {got:.8}, numpy (f64) {want:.8}");
        assert!(
            (got - want).abs() <= 2e-5 * want + 1e-6,
            "LPIPS({a}, {b}) = {got}, numpy says {want}"
        );
        let layers = net.per_layer(&p, &t).unwrap();
        for (l, (g, w)) in layers
            .iter()
            .zip(case["per_layer"].as_array().unwrap())
            .enumerate()
        {
            let w = w.as_f64().unwrap();
            assert!(
                (g - w).abs() <= 2e-5 * w + 1e-6,
                "layer {l} of ({a}, {b}): {g} vs {w}"
            );
        }
    }
}

#[test]
fn identical_images_are_at_distance_zero() {
    let net = net();
    let (w, h) = (64, 48);
    for kind in ["waves", "disc", "noise"] {
        let x = tensor(&procedural(kind, w, h), w, h);
        assert_eq!(scalar(&net.distance(&x, &x).unwrap()), 0.0, "{kind}");
    }
}

/// A `w × h` image blurred by a box of radius `r` (clamped borders).
fn box_blur(img: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let (mut s, mut n) = (0.0, 0.0);
            for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
                for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                    s += img[yy * w + xx];
                    n += 1.0;
                }
            }
            out[y * w + x] = s / n;
        }
    }
    out
}

fn add_noise(img: &[f32], noise: &[f32], amp: f32) -> Vec<f32> {
    img.iter()
        .zip(noise)
        .map(|(v, n)| (v + amp * (n - 0.5)).clamp(0.0, 1.0))
        .collect()
}

fn check_ordering(net: &Lpips, img: &[f32], w: usize, h: usize, what: &str) {
    let noise = procedural("noise", w, h);
    let x = tensor(img, w, h);
    let d = |y: Vec<f32>| scalar(&net.distance(&tensor(&y, w, h), &x).unwrap());
    let (n1, n2) = (
        d(add_noise(img, &noise, 0.1)),
        d(add_noise(img, &noise, 0.4)),
    );
    let (b1, b2) = (d(box_blur(img, w, h, 1)), d(box_blur(img, w, h, 3)));
    eprintln!("{what}: noise 0.1 → {n1:.4}, 0.4 → {n2:.4}; blur r=1 → {b1:.4}, r=3 → {b2:.4}");
    assert!(
        0.0 < n1 && n1 < n2,
        "{what}: heavier noise must be farther ({n1} vs {n2})"
    );
    assert!(
        0.0 < b1 && b1 < b2,
        "{what}: heavier blur must be farther ({b1} vs {b2})"
    );
}

#[test]
fn heavier_distortions_are_farther() {
    let net = net();
    let (w, h) = (96, 80);
    let waves = procedural("waves", w, h);
    let disc = procedural("disc", w, h);
    let texture: Vec<f32> = waves
        .iter()
        .zip(&disc)
        .map(|(a, b)| 0.6 * a + 0.4 * b)
        .collect();
    check_ordering(net, &texture, w, h, "procedural texture");
    // The same check on a photograph, when one is named (e.g. the astronaut of the data kit).
    if let Some(path) = std::env::var_os("IFSLAB_LPIPS_TEST_IMAGE") {
        let img = image::open(&path).unwrap().to_luma32f();
        let (w, h) = (img.width() as usize, img.height() as usize);
        check_ordering(
            net,
            img.as_raw(),
            w,
            h,
            &format!("{}", std::path::Path::new(&path).display()),
        );
    }
}

#[test]
fn gradient_matches_finite_differences() {
    // Per tap: d/dε LPIPS_l(x + ε·v, t) at ε = 0 (central differences, ε = 1e-7, in f64)
    // against ⟨∇LPIPS_l, v⟩ from candle autograd. LPIPS is piecewise smooth (ReLU, max-pool
    // and the normalisation have kinks), so the step must be tiny, hence f64; steps of 1e-3
    // along a noise direction cross kinks and disagree by tens of percent.
    let net = net();
    let (w, h) = (48, 40);
    let to64 = |v: Vec<f32>| v.into_iter().map(f64::from).collect::<Vec<f64>>();
    let x0 = to64(procedural("waves", w, h));
    let t = Tensor::from_vec(to64(procedural("disc", w, h)), (h, w), &Device::Cpu).unwrap();
    let v: Vec<f64> = to64(procedural("noise", w, h))
        .iter()
        .map(|n| n - 0.5)
        .collect();
    let x = Var::from_slice(&x0, (h, w), &Device::Cpu).unwrap();
    let at = |eps: f64| {
        let y: Vec<f64> = x0.iter().zip(&v).map(|(a, b)| a + eps * b).collect();
        net.per_layer(&Tensor::from_vec(y, (h, w), &Device::Cpu).unwrap(), &t)
            .unwrap()
    };
    let eps = 1e-7;
    let (up, down) = (at(eps), at(-eps));
    for (l, term) in net
        .layer_terms(x.as_tensor(), &t)
        .unwrap()
        .iter()
        .enumerate()
    {
        let g: Vec<f64> = term
            .backward()
            .unwrap()
            .get(x.as_tensor())
            .unwrap()
            .flatten_all()
            .unwrap()
            .to_vec1()
            .unwrap();
        let analytic: f64 = g.iter().zip(&v).map(|(a, b)| a * b).sum();
        let fd = (up[l] - down[l]) / (2.0 * eps);
        eprintln!("tap {l}: autograd {analytic:.9}, finite difference {fd:.9}");
        assert!(
            (analytic - fd).abs() <= 1e-5 * fd.abs() + 1e-9,
            "tap {l}: autograd {analytic} vs fd {fd}"
        );
    }
}

#[test]
fn f32_gradient_agrees_with_f64() {
    // The training path runs in f32; its gradient must match the f64 one to float precision.
    let net = net();
    let (w, h) = (48, 40);
    let x32 = procedural("waves", w, h);
    let t32 = procedural("disc", w, h);
    let grad = |dt: DType| -> Vec<f64> {
        let x = Var::from_tensor(&tensor(&x32, w, h).to_dtype(dt).unwrap()).unwrap();
        let t = tensor(&t32, w, h).to_dtype(dt).unwrap();
        let d = net.distance(x.as_tensor(), &t).unwrap();
        let g = d.backward().unwrap().get(x.as_tensor()).unwrap().clone();
        g.to_dtype(DType::F64)
            .unwrap()
            .flatten_all()
            .unwrap()
            .to_vec1()
            .unwrap()
    };
    let (g32, g64) = (grad(DType::F32), grad(DType::F64));
    let num: f64 = g32
        .iter()
        .zip(&g64)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    let den: f64 = g64.iter().map(|b| b * b).sum::<f64>().sqrt();
    assert!(num <= 1e-4 * den, "relative L2 difference {}", num / den);
}

#[test]
fn cached_target_features_and_the_objective_agree_with_distance() {
    let net = net();
    let (w, h) = (40, 36);
    let p = procedural("waves", w, h);
    let t = tensor(&procedural("disc", w, h), w, h);
    let x = Var::from_slice(&p, (h, w), &Device::Cpu).unwrap();
    let direct = net.distance(x.as_tensor(), &t).unwrap();
    let feats = net.features(&t).unwrap();
    let cached = net.distance_to(x.as_tensor(), &feats).unwrap();
    assert_eq!(scalar(&direct), scalar(&cached));
    let g_direct = direct
        .backward()
        .unwrap()
        .get(x.as_tensor())
        .unwrap()
        .clone();
    // The objective with only LPIPS (weight 2) gives twice LPIPS and twice its gradient.
    let cfg = LossConfig {
        msmse_weight: 0.0,
        dssim_weight: 0.0,
        lpips_weight: 2.0,
        lpips_weights: Some(net.weights_path().to_path_buf()),
        ..Default::default()
    };
    let obj = Objective::new(cfg, &t).unwrap();
    assert!(obj.lpips_active());
    let (total, b) = obj.image_loss(x.as_tensor()).unwrap();
    assert!((b.lpips.unwrap() - scalar(&direct)).abs() < 1e-7);
    assert!((scalar(&total) - 2.0 * scalar(&direct)).abs() < 1e-6);
    let g_obj = total
        .backward()
        .unwrap()
        .get(x.as_tensor())
        .unwrap()
        .clone();
    let diff = (g_obj - (g_direct * 2.0).unwrap())
        .unwrap()
        .abs()
        .unwrap()
        .max_all()
        .unwrap();
    assert!(diff.to_scalar::<f32>().unwrap() < 1e-6);
}

#[test]
fn too_small_images_are_refused() {
    let net = net();
    let x = Tensor::zeros((30, 64), DType::F32, &Device::Cpu).unwrap();
    let msg = net.distance(&x, &x).unwrap_err().to_string();
    assert!(msg.contains("at least 31×31"), "{msg}");
}

/// RGB images go through AlexNet as RGB: a colour image whose three channels are one grey
/// image is at the grey image's distance, different colours of the same luminance layout are
/// not at distance zero, and the gradient with respect to every channel matches finite
/// differences (f64, ε = 1e-7, along a noise direction).
#[test]
fn rgb_images_are_compared_in_colour() {
    let net = net();
    let (w, h) = (40, 36);
    let dev = Device::Cpu;
    let to64 = |v: Vec<f32>| v.into_iter().map(f64::from).collect::<Vec<f64>>();
    let (a, b) = (
        to64(procedural("waves", w, h)),
        to64(procedural("disc", w, h)),
    );
    let grey = |v: &[f64]| Tensor::from_vec(v.to_vec(), (h, w), &dev).unwrap();
    let rgb = |v: Vec<f64>| Tensor::from_vec(v, (3, h, w), &dev).unwrap();
    let d_grey = scalar(&net.distance(&grey(&a), &grey(&b)).unwrap());
    let d_rgb = scalar(&net.distance(&rgb(a.repeat(3)), &rgb(b.repeat(3))).unwrap());
    assert!((d_grey - d_rgb).abs() < 1e-12, "{d_grey} vs {d_rgb}");
    // The same picture in red and in blue.
    let zeros = vec![0.0; w * h];
    let red = rgb([a.clone(), zeros.clone(), zeros.clone()].concat());
    let blue = rgb([zeros.clone(), zeros.clone(), a.clone()].concat());
    assert!(scalar(&net.distance(&red, &blue).unwrap()) > 0.01);
    // Gradient through each channel.
    let x0 = [a.clone(), b.clone(), a.iter().map(|v| 1.0 - v).collect()].concat();
    let t = rgb([b.clone(), a.clone(), b.clone()].concat());
    let dir: Vec<f64> = to64(procedural("noise", w, h))
        .repeat(3)
        .iter()
        .enumerate()
        .map(|(i, n)| (n - 0.5) * [1.0, -0.5, 0.25][i / (w * h)])
        .collect();
    let x = Var::from_vec(x0.clone(), (3, h, w), &dev).unwrap();
    let g: Vec<f64> = net
        .distance(x.as_tensor(), &t)
        .unwrap()
        .backward()
        .unwrap()
        .get(x.as_tensor())
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1()
        .unwrap();
    let at = |eps: f64| {
        let y: Vec<f64> = x0.iter().zip(&dir).map(|(a, b)| a + eps * b).collect();
        scalar(&net.distance(&rgb(y), &t).unwrap())
    };
    let eps = 1e-7;
    let fd = (at(eps) - at(-eps)) / (2.0 * eps);
    let analytic: f64 = g.iter().zip(&dir).map(|(a, b)| a * b).sum();
    assert!(
        (analytic - fd).abs() <= 1e-5 * fd.abs() + 1e-9,
        "autograd {analytic} vs fd {fd}"
    );
    // Each channel gets its own gradient.
    let n = w * h;
    let norms: Vec<f64> = g
        .chunks_exact(n)
        .map(|c| c.iter().map(|v| v * v).sum::<f64>())
        .collect();
    assert!(norms.iter().all(|&v| v > 0.0), "{norms:?}");
    // Two channels are neither grey nor RGB.
    let two = Tensor::from_vec([a.clone(), b.clone()].concat(), (2, h, w), &dev).unwrap();
    let e = net.distance(&two, &two).unwrap_err();
    assert!(e.to_string().contains("2 channels"), "{e}");
}
