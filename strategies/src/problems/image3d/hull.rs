//! The visual-hull start: the voxels of a cube whose projections meet the ink of every
//! view (space carving, Laurentini's visual hull), points drawn in them, and an IFS of
//! similitudes fitted to those points by EM in 3-D ([`crate::problems::em`]). That code is
//! the multi-view fit's start and the baseline the fit must beat.
//!
//! A voxel is kept when, in every view, the pixels its eight corners' projections span hold
//! ink at least `threshold` — a conservative test: a thin structure that crosses a voxel
//! keeps it even when it misses the voxel's centre. A voxel that some camera cannot see
//! (outside its image, behind it) is carved.
//!
//! ## References
//! - A. Laurentini, *The visual hull concept for silhouette-based image understanding*,
//!   IEEE TPAMI 16(2), 1994.
//! - P. Bloem and S. de Rooij, *An Expectation-Maximization Algorithm for the Fractal
//!   Inverse Problem*, arXiv:1706.03149, 2017.

use ifslab::chaos::{mix_seed, trajectory_rng};
use ifslab::model::map3::{Affine3, SVD3_PARAMS, SvdMap3};
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::problems::em::{EmConfig, PointSet, fit};
use crate::problems::image3d::views::Views;

/// How the hull is carved and the EM start fitted.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HullConfig {
    /// Voxels per side of the carved cube.
    pub resolution: usize,
    /// The cube is `[−extent, extent]³` (world units).
    pub extent: f64,
    /// Ink level in (0, 1] a voxel's pixels must reach in every view.
    pub threshold: f64,
    /// Points drawn in the kept voxels for EM.
    pub points: usize,
    /// EM's depth.
    pub em_depth: usize,
    /// EM's iterations at that depth.
    pub em_iterations: usize,
    /// EM's pre-selection pool.
    pub em_pool: usize,
}

impl Default for HullConfig {
    fn default() -> Self {
        HullConfig {
            resolution: 64,
            extent: 1.0,
            threshold: 0.3,
            points: 3000,
            em_depth: 5,
            em_iterations: 100,
            em_pool: 4,
        }
    }
}

impl HullConfig {
    /// Checks every field; the error names the one to change.
    pub fn validate(&self) -> Result<()> {
        if !(2..=512).contains(&self.resolution) {
            return Err(Error::param(
                "hull.resolution",
                format!("must lie in 2..=512, got {}", self.resolution),
            ));
        }
        if !(self.extent.is_finite() && self.extent > 0.0) {
            return Err(Error::param(
                "hull.extent",
                format!("must be finite and > 0, got {}", self.extent),
            ));
        }
        if !(self.threshold > 0.0 && self.threshold <= 1.0) {
            return Err(Error::param(
                "hull.threshold",
                format!("must lie in (0, 1], got {}", self.threshold),
            ));
        }
        if self.points < 10 {
            return Err(Error::param(
                "hull.points",
                format!("must be at least 10, got {}", self.points),
            ));
        }
        if self.em_depth == 0 || self.em_iterations == 0 || self.em_pool == 0 {
            return Err(Error::param(
                "hull.em_depth",
                "em_depth, em_iterations and em_pool must each be at least 1",
            ));
        }
        Ok(())
    }
}

/// The carved hull: the kept voxels of the cube.
#[derive(Clone, Debug, PartialEq)]
pub struct Hull {
    /// Voxels per side.
    pub resolution: usize,
    /// Half the cube's side.
    pub extent: f64,
    /// Indices `x + r·(y + r·z)` of the kept voxels, increasing.
    pub kept: Vec<usize>,
}

impl Hull {
    /// A voxel's side.
    pub fn voxel(&self) -> f64 {
        2.0 * self.extent / self.resolution as f64
    }

    /// The lowest corner of voxel `index`.
    fn corner(&self, index: usize) -> [f64; 3] {
        let r = self.resolution;
        let v = self.voxel();
        let (x, y, z) = (index % r, (index / r) % r, index / (r * r));
        [x, y, z].map(|i| -self.extent + i as f64 * v)
    }

    /// The centres of the kept voxels.
    pub fn centres(&self) -> Vec<[f64; 3]> {
        let h = 0.5 * self.voxel();
        self.kept
            .iter()
            .map(|&i| self.corner(i).map(|c| c + h))
            .collect()
    }

    /// `n` points in the kept voxels: voxel `⌊j·K/n⌋` for point `j` (every voxel as often
    /// as the others, within one), at a uniform place inside it drawn from `seed`.
    pub fn sample(&self, n: usize, seed: u64) -> Vec<[f64; 3]> {
        let k = self.kept.len();
        let v = self.voxel();
        let mut rng = trajectory_rng(mix_seed(seed, 0x4855_4c4c), 0);
        (0..n)
            .map(|j| {
                let c = self.corner(self.kept[j * k / n]);
                c.map(|c| c + v * rng.random::<f64>())
            })
            .collect()
    }
}

/// Carves the hull of `views` (see the module docs); refuses an empty hull, saying what to
/// check.
pub fn visual_hull(views: &Views, cfg: &HullConfig) -> Result<Hull> {
    cfg.validate()?;
    let r = cfg.resolution;
    let (w, h) = views.size();
    let empty = Hull {
        resolution: r,
        extent: cfg.extent,
        kept: Vec::new(),
    };
    let v = empty.voxel();
    let threshold = cfg.threshold as f32;
    let inked = |view: usize, corner: [f64; 3]| -> bool {
        let cam = &views.cameras[view];
        let plane = views.plane(view);
        let (mut u0, mut u1, mut v0, mut v1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for k in 0..8 {
            let p = [
                corner[0] + v * (k & 1) as f64,
                corner[1] + v * ((k >> 1) & 1) as f64,
                corner[2] + v * ((k >> 2) & 1) as f64,
            ];
            let Some([u, vv]) = cam.project(p) else {
                return false;
            };
            u0 = u0.min(u);
            u1 = u1.max(u);
            v0 = v0.min(vv);
            v1 = v1.max(vv);
        }
        if u1 < 0.0 || v1 < 0.0 || u0 >= w as f64 || v0 >= h as f64 {
            return false;
        }
        let (i0, i1) = (u0.max(0.0) as usize, (u1.max(0.0) as usize).min(w - 1));
        let (j0, j1) = (v0.max(0.0) as usize, (v1.max(0.0) as usize).min(h - 1));
        (j0..=j1).any(|j| (i0..=i1).any(|i| plane[j * w + i] >= threshold))
    };
    let kept: Vec<usize> = (0..r * r * r)
        .into_par_iter()
        .with_min_len(1024)
        .filter(|&i| {
            let c = empty.corner(i);
            (0..views.len()).all(|view| inked(view, c))
        })
        .collect();
    if kept.is_empty() {
        return Err(Error::InvalidInput(format!(
            "the visual hull is empty: no voxel of [−{e}, {e}]³ projects onto ink in every \
             view; check that the cameras belong to the pictures (pose convention, order) and \
             that the shape lies inside the cube (raise hull.extent)",
            e = cfg.extent
        )));
    }
    Ok(Hull { kept, ..empty })
}

/// Largest singular value and largest |offset| a start may have: the SVD
/// parameterisation's cap is 1 and its offsets lie in (−1, 1)³; a start at the bound would
/// have infinite θ.
const START_BOUND: f64 = 0.95;

/// `map` brought inside what [`SvdMap3`] reaches: its matrix scaled down to singular values
/// at most [`START_BOUND`], its offset clamped to `[−START_BOUND, START_BOUND]³`, then
/// encoded.
pub fn encode_start(map: &Affine3) -> Result<SvdMap3> {
    let mut a = *map;
    let s = a.sigma_max();
    if s > START_BOUND {
        a.m *= START_BOUND / s;
    }
    for b in a.b.iter_mut() {
        *b = b.clamp(-START_BOUND, START_BOUND);
    }
    Ok(SvdMap3::from_affine(&a, 1e-6)?)
}

/// The hull's EM start: an IFS of `maps` similitudes fitted by EM to points of the hull,
/// as SVD maps ([`encode_start`]); `seed` seeds the points and EM.
pub fn hull_start(hull: &Hull, maps: usize, cfg: &HullConfig, seed: u64) -> Result<Vec<SvdMap3>> {
    let points = hull.sample(cfg.points, seed);
    let data = PointSet::new(3, points.iter().flatten().copied().collect())?;
    let em = EmConfig {
        components: maps,
        depth: cfg.em_depth,
        iterations: cfg.em_iterations,
        pool: cfg.em_pool,
        preselect_iterations: cfg.em_iterations.min(60),
        seed,
        ..EmConfig::default()
    };
    let result = fit(&data, None, &em, &mut |_| {})?;
    let code = result.model.to_code(None)?;
    Affine3::from_code(&code)?
        .iter()
        .map(encode_start)
        .collect()
}

/// A random start of `maps` SVD maps drawn from `seed`: uniform rotations (normal
/// quaternions), singular values `sigmoid(N(0, 1))`, offsets `tanh(N(0, 0.5²))`, no
/// reflection.
pub fn random_start(maps: usize, seed: u64) -> Result<Vec<SvdMap3>> {
    let mut rng = trajectory_rng(mix_seed(seed, 0x5241_4e44), 0);
    (0..maps)
        .map(|_| {
            let mut theta = [0.0; SVD3_PARAMS];
            for (k, t) in theta.iter_mut().enumerate() {
                let z: f64 = StandardNormal.sample(&mut rng);
                *t = if k >= 11 { 0.5 * z } else { z };
            }
            Ok(SvdMap3::new(&theta, false)?)
        })
        .collect()
}
