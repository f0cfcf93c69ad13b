//! Random IFS codes with the Anderson–Farrell singular-value sampler.
//!
//! Codes drawn uniformly at random are mostly dust or blobs. Anderson & Farrell bound the
//! "σ-factor" Σᵢ (σ₁ᵢ + 2·σ₂ᵢ) of an n-map code to `[(5 + n)/2, (6 + n)/2]`, where codes
//! tend to be visually rich, and draw the singular values of every map so the sum lands on
//! a target drawn from that interval while each map stays contractive (σ₂ ≤ σ₁ < 1).
//! Rotations and reflections come from U, V = rotation(ψ)·diag(±1, ±1), translations from
//! U(−1, 1)². The chaotic-splatting paper uses this sampler (10 maps) for its test suite.
//!
//! ## References
//! - Anderson & Farrell, *Improving Fractal Pre-training*, WACV 2022.

use nalgebra::Matrix2;
use rand::Rng;
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;

use crate::error::{Error, Result};
use crate::model::affine::Affine2;

/// A code drawn by [`sample_code`], with the numbers that explain it.
#[derive(Clone, Debug)]
pub struct SampledCode {
    /// The maps.
    pub maps: Vec<Affine2>,
    /// Singular values `(σ₁, σ₂)` of each map, as drawn.
    pub singular_values: Vec<(f64, f64)>,
    /// The σ-factor target `a`, drawn from [`sigma_factor_bounds`].
    pub sigma_factor: f64,
}

/// The interval `[(5 + n)/2, (6 + n)/2]` the σ-factor of an `n`-map code is drawn from.
pub fn sigma_factor_bounds(n: usize) -> (f64, f64) {
    ((5.0 + n as f64) / 2.0, (6.0 + n as f64) / 2.0)
}

/// The σ-factor Σ (σ₁ + 2σ₂) of a set of maps.
pub fn sigma_factor(maps: &[Affine2]) -> f64 {
    maps.iter()
        .map(|m| {
            let (a, b) = m.singular_values();
            a + 2.0 * b
        })
        .sum()
}

fn uniform<R: Rng>(rng: &mut R, lo: f64, hi: f64) -> f64 {
    if hi <= lo {
        lo
    } else {
        rng.random_range(lo..hi)
    }
}

fn random_orthogonal<R: Rng>(rng: &mut R) -> Matrix2<f64> {
    let psi = uniform(rng, -std::f64::consts::PI, std::f64::consts::PI);
    let (s, c) = psi.sin_cos();
    let d1 = if rng.random::<bool>() { 1.0 } else { -1.0 };
    let d2 = if rng.random::<bool>() { 1.0 } else { -1.0 };
    Matrix2::new(c, -s, s, c) * Matrix2::new(d1, 0.0, 0.0, d2)
}

/// Draws singular values `(σ₁, σ₂)` for `n` maps whose σ-factor is exactly `a`.
fn draw_singular_values<R: Rng>(rng: &mut R, n: usize, a: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    let mut p = a;
    let mut q = a - 3.0 * n as f64 + 3.0;
    for _ in 0..n - 1 {
        let s1 = uniform(rng, (q / 3.0).max(0.0), p.min(1.0));
        q -= s1;
        p -= s1;
        let s2 = uniform(rng, (q / 2.0).max(0.0), s1.min(p / 2.0));
        q = q - 2.0 * s2 + 3.0;
        p -= 2.0 * s2;
        out.push((s1, s2));
    }
    let s2 = uniform(rng, ((p - 1.0) / 2.0).max(0.0), p / 3.0);
    out.push((p - 2.0 * s2, s2));
    out
}

/// A random `n`-map code from the Anderson–Farrell sampler, reproducible from `seed`.
///
/// The rare draw that lands on σ₁ = 1 exactly (not contractive) is redrawn.
pub fn sample_code(n: usize, seed: u64) -> Result<SampledCode> {
    if n < 2 {
        return Err(Error::param(
            "maps",
            format!("the sampler needs at least 2 maps, got {n}"),
        ));
    }
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let (lo, hi) = sigma_factor_bounds(n);
    loop {
        let a = uniform(&mut rng, lo, hi);
        let svs = draw_singular_values(&mut rng, n, a);
        if svs
            .iter()
            .any(|&(s1, s2)| !(s1 < 1.0 && s2 >= 0.0 && s2 <= s1 + 1e-12))
        {
            continue;
        }
        let maps = svs
            .iter()
            .map(|&(s1, s2)| {
                let u = random_orthogonal(&mut rng);
                let v = random_orthogonal(&mut rng);
                let m = u * Matrix2::new(s1, 0.0, 0.0, s2) * v.transpose();
                let e = uniform(&mut rng, -1.0, 1.0);
                let f = uniform(&mut rng, -1.0, 1.0);
                Affine2 {
                    m,
                    b: nalgebra::Vector2::new(e, f),
                }
            })
            .collect();
        return Ok(SampledCode {
            maps,
            singular_values: svs,
            sigma_factor: a,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampled_codes_hit_their_sigma_factor() {
        for seed in 0..50 {
            let c = sample_code(10, seed).unwrap();
            assert!((sigma_factor(&c.maps) - c.sigma_factor).abs() < 1e-9);
            assert!(c.maps.iter().all(|m| m.sigma_max() < 1.0));
        }
    }
}
