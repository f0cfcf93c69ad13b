//! Initial models: K random fixed points on the unit sphere, scale ½, Haar-random rotations,
//! uniform weights and depth weights, and a post-transform that maps the unit ball onto the
//! data (its mean and RMS radius).
//!
//! Each map is built around its fixed point p: `S(x) = p + s·R·(x − p)`, i.e. `t = p − s·R·p`,
//! so every initial map pulls the space towards a different point of the sphere. The
//! post-transform makes the algorithm equivariant to similarity transforms of the data.
//!
//! ## References
//! - P. Bloem and S. de Rooij, *An Expectation-Maximization Algorithm for the Fractal
//!   Inverse Problem*, arXiv:1706.03149, 2017 (the initialisation).

use nalgebra::{DMatrix, DVector};
use rand::Rng;
use rand_distr::StandardNormal;

use ifslab::model::Similitude;
use ifslab::model::similitude::random_rotation;

use crate::error::{Error, Result};
use crate::problems::em::data::PointSet;
use crate::problems::em::model::EmModel;

/// The post-transform `x ↦ ρ·x + m` with m the data's mean and ρ its RMS radius (1 if the
/// points all coincide).
pub fn normalising_post(points: &PointSet) -> Similitude {
    let h = points.dim();
    let rho = points.rms_radius();
    Similitude {
        s: if rho > 0.0 && rho.is_finite() {
            rho
        } else {
            1.0
        },
        r: DMatrix::identity(h, h),
        t: DVector::from_vec(points.mean()),
    }
}

/// A point drawn uniformly from the unit sphere in R^h (±1 when h = 1).
pub fn sphere_point<R: Rng + ?Sized>(h: usize, rng: &mut R) -> DVector<f64> {
    loop {
        let g = DVector::<f64>::from_fn(h, |_, _| rng.sample(StandardNormal));
        let n = g.norm();
        if n > 1e-12 {
            return g / n;
        }
    }
}

/// A random model of `k` components at depth `depth` (uniform weights and depth weights),
/// each map of scale `scale` around a random fixed point on the unit sphere with a Haar
/// rotation, and the given post-transform.
pub fn random_model<R: Rng + ?Sized>(
    k: usize,
    depth: usize,
    scale: f64,
    post: Similitude,
    rng: &mut R,
) -> Result<EmModel> {
    if k == 0 {
        return Err(Error::param("k", "need at least one component"));
    }
    if !(scale > 0.0 && scale < 1.0) {
        return Err(Error::param(
            "init_scale",
            format!("must lie in (0, 1), got {scale}"),
        ));
    }
    let h = post.dim();
    let components = (0..k)
        .map(|_| {
            let p = sphere_point(h, rng);
            let r = random_rotation(h, rng);
            let t = &p - (&r * &p) * scale;
            Similitude { s: scale, r, t }
        })
        .collect();
    EmModel::new(
        components,
        vec![1.0 / k as f64; k],
        vec![1.0 / (depth + 1) as f64; depth + 1],
        post,
    )
}
