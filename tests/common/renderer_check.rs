//! The generic reverse-pass check `tests/renderer.rs` and `tests/three_d.rs` include
//! (`#[path = "common/renderer_check.rs"] mod renderer_check;`): a renderer's `∂L/∂θ`
//! against central finite differences in f64, through the `Renderer` trait.
//!
//! The loss is linear in the image, `L = Σ wₖ·imageₖ` with fixed weights, so
//! `∂L/∂image = w` and `∂L/∂θ` is exactly the vector–Jacobian product the renderer's reverse
//! pass computes; its central difference is taken on the same sampling state.

use std::borrow::Borrow;

use ifslab::render::{Renderer, value_and_grad};

/// Fixed weights in [−0.4, 0.6), one per image value.
pub fn weights(n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| ((k as f64) * 0.618_033_988_7).fract() - 0.4)
        .collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Checks `renderer`'s reverse pass at `theta` (the scene `scene_at(θ)`) against central
/// differences with step `h`: every entry within `tol·(1 + |fd|)`. Returns the largest
/// |finite difference|, so the caller can check that the loss depends on θ at all.
pub fn reverse_pass_matches_finite_differences<R, S>(
    name: &str,
    renderer: &R,
    theta: &[f64],
    scene_at: impl Fn(&[f64]) -> S,
    h: f64,
    tol: f64,
) -> f64
where
    R: Renderer<Pixel = f64>,
    S: Borrow<R::Scene>,
{
    let planes = renderer.planes();
    let scene = scene_at(theta);
    let sampling = renderer.sampling(scene.borrow(), 11, 0);
    let w = weights(planes.len());
    let (value, grad) = value_and_grad(renderer, scene.borrow(), &sampling, |image| {
        assert_eq!(
            image.len(),
            planes.len(),
            "{name}: the image has its planes"
        );
        Ok::<_, ifslab::Error>((dot(image, &w), w.clone()))
    })
    .unwrap();
    assert!(value.is_finite(), "{name}: L = {value}");
    assert_eq!(
        grad.len(),
        theta.len(),
        "{name}: one derivative per parameter"
    );
    let loss = |t: &[f64]| {
        dot(
            &renderer.forward(scene_at(t).borrow(), &sampling).unwrap().0,
            &w,
        )
    };
    let mut scale = 0.0f64;
    for k in 0..theta.len() {
        let (mut up, mut down) = (theta.to_vec(), theta.to_vec());
        up[k] += h;
        down[k] -= h;
        let fd = (loss(&up) - loss(&down)) / (2.0 * h);
        scale = scale.max(fd.abs());
        assert!(
            (fd - grad[k]).abs() <= tol * (1.0 + fd.abs()),
            "{name}, θ[{k}]: analytic {} vs finite difference {fd}",
            grad[k]
        );
    }
    scale
}
