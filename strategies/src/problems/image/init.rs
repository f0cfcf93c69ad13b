//! Where an image inversion starts: a random Anderson–Farrell code, a given code, or — going
//! beyond the splatting paper — an IFS of similitudes fitted by EM to points drawn from the
//! target image, which the splatting strategies then refine into general affine maps.
//!
//! Gradient descent on the rendered image is local: from a random code it often settles in
//! a thin or tangled attractor. EM on a point cloud (Bloem & de Rooij) is a cheap, global
//! fit of the same kind of model (with pre-selection among random starts), so it lands in
//! the right basin far more often; the image loss then corrects what similitudes cannot
//! express (shears, reflections, anisotropic scales).

use ifslab::chaos::{mix_seed, trajectory_rng};
use ifslab::model::random::sample_code;
use ifslab::model::{Affine2, IfsCode, library};
use nalgebra::{Matrix2, Vector2};
use rand::Rng;
use rand_distr::StandardNormal;

use crate::error::{Error, Result};
use crate::problems::em::{EmConfig, PointSet, fit};
use crate::problems::image::config::{InitKind, InversionConfig};
use crate::problems::image::model::AnyModel;

/// Points drawn from a `size × size` image with probability ∝ intensity, jittered inside
/// their pixel, in coordinates `[−1, 1]²` (y up).
pub fn sample_image_points(image: &[f32], size: usize, n: usize, seed: u64) -> Result<PointSet> {
    let mut cdf = Vec::with_capacity(image.len());
    let mut acc = 0.0f64;
    for &v in image {
        acc += v.max(0.0) as f64;
        cdf.push(acc);
    }
    if acc <= 0.0 || acc.is_nan() {
        return Err(Error::InvalidInput(
            "the target has no bright pixels to sample points from".into(),
        ));
    }
    let mut rng = trajectory_rng(mix_seed(seed, 0xE11), 0);
    let mut data = Vec::with_capacity(2 * n);
    for _ in 0..n {
        let u = rng.random::<f64>() * acc;
        let i = cdf.partition_point(|&c| c <= u).min(image.len() - 1);
        let (px, py) = ((i % size) as f64, (i / size) as f64);
        let x = (px + rng.random::<f64>()) / size as f64 * 2.0 - 1.0;
        let y = 1.0 - (py + rng.random::<f64>()) / size as f64 * 2.0;
        data.extend_from_slice(&[x, y]);
    }
    PointSet::new(2, data)
}

/// An IFS of `k` similitudes fitted by EM (paper settings: depth 6, 300 iterations,
/// N′ = 500, pool 10) to 4000 points of the target, as affine maps. With many maps the depth
/// is lowered so that the K^D codes stay near 5000 (K = 10: depth 3).
/// With `reflections`, the similitudes may mirror as well as rotate.
pub fn em_initial_maps(
    target: &[f32],
    size: usize,
    k: usize,
    seed: u64,
    reflections: bool,
) -> Result<Vec<Affine2>> {
    let points = sample_image_points(target, size, 4000, seed)?;
    let depth = if k <= 4 {
        6
    } else {
        ((5000f64.ln() / (k as f64).ln()).floor() as usize).clamp(2, 6)
    };
    let base = EmConfig::default();
    let cfg = EmConfig {
        components: k,
        depth,
        preselect_depth: depth.min(3),
        seed,
        mstep: crate::problems::em::MStepConfig {
            reflections,
            ..base.mstep.clone()
        },
        ..base
    };
    let res = fit(&points, None, &cfg, &mut |_| {})?;
    Ok(res
        .model
        .data_space_maps()
        .iter()
        .map(|s| {
            let m = &s.r * s.s;
            Affine2 {
                m: Matrix2::new(m[(0, 0)], m[(0, 1)], m[(1, 0)], m[(1, 1)]),
                b: Vector2::new(s.t[0], s.t[1]),
            }
        })
        .collect())
}

/// Scales every offset by one factor so all lie within ±`bound` (the attractor scales by
/// the same factor about the origin; the renderers' framing does not see it).
fn fit_offsets(maps: &mut [Affine2], bound: f64) {
    let max = maps
        .iter()
        .flat_map(|m| [m.b[0].abs(), m.b[1].abs()])
        .fold(0.0f64, f64::max);
    if max > bound {
        for m in maps.iter_mut() {
            m.b *= bound / max;
        }
    }
}

/// The starting θ: the code `model.init_code` if given, else per `model.init` a random
/// Anderson–Farrell code (seeded by `model.init_seed`, else the run's seed) or an EM fit to
/// the target; offsets are brought inside the SVD parameterisation's open square, and
/// `model.init_noise` Gaussian noise is added.
pub fn initial_theta(
    cfg: &InversionConfig,
    model: &dyn AnyModel,
    target: &[f32],
) -> Result<Vec<f64>> {
    let n = cfg.model.maps;
    let seed = cfg.model.init_seed.unwrap_or(cfg.seed);
    let mut maps: Vec<Affine2> = match &cfg.model.init_code {
        Some(spec) => {
            let code = if std::path::Path::new(spec).is_file() {
                IfsCode::load(spec)?
            } else {
                library::builtin(spec)?
            };
            let maps = code.affine2()?;
            if maps.len() != n {
                return Err(Error::InvalidInput(format!(
                    "config field `model.init_code`: `{spec}` has {} maps but `model.maps` is {n}",
                    maps.len()
                )));
            }
            maps
        }
        None => match cfg.model.init {
            InitKind::Em => {
                em_initial_maps(target, cfg.target.size, n, seed, cfg.model.em_reflections)?
            }
            InitKind::Random if n >= 2 => sample_code(n, seed)?.maps,
            InitKind::Random => vec![Affine2::new(0.5, 0.0, 0.0, 0.5, 0.1, 0.1)],
        },
    };
    if cfg.model.init_code.is_none() {
        fit_offsets(&mut maps, 0.9);
    }
    let mut theta = model.encode(&maps)?;
    if cfg.model.init_noise > 0.0 {
        let mut rng = trajectory_rng(mix_seed(seed, u64::MAX), 0);
        for t in theta.iter_mut() {
            *t += cfg.model.init_noise * rng.sample::<f64, _>(StandardNormal);
        }
        model.project(&mut theta);
    }
    Ok(theta)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampled_points_follow_the_image() {
        // Only the top-left quarter is bright.
        let size = 16;
        let img: Vec<f32> = (0..size * size)
            .map(|i| {
                if i % size < 8 && i / size < 8 {
                    1.0
                } else {
                    0.0
                }
            })
            .collect();
        let p = sample_image_points(&img, size, 500, 3).unwrap();
        for pt in p.iter() {
            assert!(
                pt[0] <= 0.0 && pt[1] >= 0.0,
                "{pt:?} outside the bright quarter"
            );
        }
    }
}
