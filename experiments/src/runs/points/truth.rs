//! Comparing a fit with the code that made the data (2-D or 3-D): the agreement of the two
//! attractors' coverage and the largest difference of their sorted scales, since a run can
//! meet the convergence criterion with a wrong code.

use crate::error::{Context, bail};
use ifslab::chaos::{ChaosGame, generate_nd};
use ifslab::model::IfsCode;
use ifslab::render::{RenderConfig, RenderMode, View, render};
use ifslab_strategies::problems::em::EmModel;

use crate::codes::resolve_code;

/// A fit counts as right when its coverage agreement with the truth reaches this.
pub const RIGHT_AGREEMENT: f64 = 0.9;

/// Side of the coverage masks compared with the truth (2-D).
pub const TRUTH_SIZE: u32 = 128;
/// Side of the voxel grids compared with the truth (3-D).
pub const TRUTH_VOXELS: usize = 64;
/// Points per coverage render.
const TRUTH_POINTS: u64 = 2_000_000;

/// Where the truth's attractor lies and which cells it covers.
enum Cover {
    /// A 2-D coverage mask in the window the attractor fills.
    Pixels { window: View, mask: Vec<bool> },
    /// A 3-D voxel grid: the cube with corner `lo` and side `side`, cells covered.
    Voxels {
        lo: Vec<f64>,
        side: f64,
        mask: Vec<bool>,
    },
}

/// The code that made the data: its sorted scales and its coverage of the region its
/// attractor fills.
pub struct Truth {
    scales: Vec<f64>,
    cover: Cover,
}

/// How one fit compares with the truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Against {
    /// Coverage agreement ([`tolerant_agreement`]), 1 for equal attractors.
    pub agreement: f64,
    /// Plain IoU of the same coverage masks (no tolerance).
    pub iou: f64,
    /// Largest difference of the sorted scales (∞ when the map counts differ).
    pub scale_error: f64,
}

impl Against {
    /// Whether the fit is right ([`RIGHT_AGREEMENT`]).
    pub fn is_right(&self) -> bool {
        self.agreement >= RIGHT_AGREEMENT
    }
}

/// Coverage mask of a 2-D code in `view`, and the window it was drawn in.
fn coverage(code: &IfsCode, view: View, seed: u64) -> crate::Result<(Vec<bool>, View)> {
    let maps = code.affine2()?;
    let probs = code.evaluation_probabilities()?;
    let cfg = RenderConfig {
        width: TRUTH_SIZE,
        height: TRUTH_SIZE,
        points: TRUTH_POINTS,
        mode: RenderMode::Coverage,
        seed,
        view,
        ..RenderConfig::default()
    };
    let r = render(&maps, &probs, &cfg, None)?;
    Ok((
        r.values.iter().map(|&v| v > 0.0).collect(),
        View::Window(r.stats.window),
    ))
}

/// About `n` points (a whole number of trajectories of 1000) of a code's attractor (any
/// dimension, flat), by the chaos game from `seed` with the evaluation renders'
/// probabilities.
pub(crate) fn attractor_points(code: &IfsCode, n: usize, seed: u64) -> crate::Result<Vec<f64>> {
    let probs = code.evaluation_probabilities()?;
    let per = 1000usize;
    let game = ChaosGame {
        trajectories: n.div_ceil(per),
        length: per + 30,
        warmup: 30,
        start_half_width: 1.0,
        seed,
    };
    Ok(generate_nd(&game, &code.maps, &probs)?)
}

/// The voxels of the `TRUTH_VOXELS³` grid over the cube (`lo`, `side`) that `points` (3-D,
/// flat) fall in; points outside the cube are not counted.
fn voxels(points: &[f64], lo: &[f64], side: f64) -> Vec<bool> {
    let n = TRUTH_VOXELS;
    let mut mask = vec![false; n * n * n];
    for p in points.chunks_exact(3) {
        let idx: Vec<f64> = (0..3).map(|k| (p[k] - lo[k]) / side * n as f64).collect();
        if idx
            .iter()
            .all(|&i| i.is_finite() && i >= 0.0 && i < n as f64)
        {
            let (x, y, z) = (idx[0] as usize, idx[1] as usize, idx[2] as usize);
            mask[(z * n + y) * n + x] = true;
        }
    }
    mask
}

impl Truth {
    /// The truth named by `spec` (a code file or a built-in name) for data of dimension
    /// `dim`: a 2-D or 3-D code of similitudes (reflections allowed).
    pub fn load(spec: &str, dim: usize) -> crate::Result<Truth> {
        let code = resolve_code(spec).with_context(|| format!("`truth` {spec}"))?;
        if code.dim() != dim || !(2..=3).contains(&dim) {
            bail!(
                "`truth` compares 2-D or 3-D attractors of the data's dimension; the code is \
                 {}-D and the data {dim}-D",
                code.dim()
            );
        }
        let mut scales = Vec::new();
        for (i, m) in code.maps.iter().enumerate() {
            let d = m.m.determinant().abs();
            if !d.is_finite() || d <= 0.0 {
                bail!("`truth` {spec}: map {i} is singular, not a similitude");
            }
            scales.push(d.powf(1.0 / dim as f64));
        }
        scales.sort_by(f64::total_cmp);
        let cover = if dim == 2 {
            let (mask, window) = coverage(&code, View::Fit, 0)?;
            Cover::Pixels { window, mask }
        } else {
            let pts = attractor_points(&code, TRUTH_POINTS as usize, 0)?;
            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for p in pts.chunks_exact(3) {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            // A cube around the attractor's box with a 5 % margin, the box centred in it.
            let side = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max) * 1.1;
            if !(side.is_finite() && side > 0.0) {
                bail!("`truth` {spec}: the attractor has no extent");
            }
            let lo: Vec<f64> = (0..3).map(|k| 0.5 * (lo[k] + hi[k]) - 0.5 * side).collect();
            let mask = voxels(&pts, &lo, side);
            Cover::Voxels { lo, side, mask }
        };
        Ok(Truth { scales, cover })
    }

    /// How a fitted model compares with the truth.
    pub fn compare(&self, model: &EmModel) -> crate::Result<Against> {
        let code = model.to_code(None)?;
        let (agreement, iou) = match &self.cover {
            Cover::Pixels {
                window,
                mask: truth,
            } => {
                let (mask, _) = coverage(&code, *window, 0)?;
                (
                    tolerant_agreement(truth, &mask, TRUTH_SIZE as usize),
                    plain_iou(truth, &mask),
                )
            }
            Cover::Voxels {
                lo,
                side,
                mask: truth,
            } => {
                let mask = voxels(
                    &attractor_points(&code, TRUTH_POINTS as usize, 0)?,
                    lo,
                    *side,
                );
                (
                    tolerant_agreement_3d(truth, &mask, TRUTH_VOXELS),
                    plain_iou(truth, &mask),
                )
            }
        };
        let mut scales: Vec<f64> = model.components.iter().map(|c| c.s.abs()).collect();
        scales.sort_by(f64::total_cmp);
        let scale_error = if scales.len() == self.scales.len() {
            scales
                .iter()
                .zip(&self.scales)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        } else {
            f64::INFINITY
        };
        Ok(Against {
            agreement,
            iou,
            scale_error,
        })
    }
}

/// IoU of two masks (1 when both are empty).
fn plain_iou(a: &[bool], b: &[bool]) -> f64 {
    let inter = a.iter().zip(b).filter(|(x, y)| **x && **y).count();
    let union = a.iter().zip(b).filter(|(x, y)| **x || **y).count();
    if union == 0 {
        1.0
    } else {
        inter as f64 / union as f64
    }
}

/// `a` grown by one voxel in every direction (3×3×3 neighbourhood) on an `n³` grid.
fn dilate_3d(a: &[bool], n: usize) -> Vec<bool> {
    let mut out = vec![false; a.len()];
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                if a[(z * n + y) * n + x] {
                    for zz in z.saturating_sub(1)..(z + 2).min(n) {
                        for yy in y.saturating_sub(1)..(y + 2).min(n) {
                            for xx in x.saturating_sub(1)..(x + 2).min(n) {
                                out[(zz * n + yy) * n + xx] = true;
                            }
                        }
                    }
                }
            }
        }
    }
    out
}

/// [`tolerant_agreement`] of two `n³` voxel grids, one voxel of tolerance.
pub fn tolerant_agreement_3d(a: &[bool], b: &[bool], n: usize) -> f64 {
    agreement_of(a, b, &dilate_3d(a, n), &dilate_3d(b, n))
}

fn agreement_of(a: &[bool], b: &[bool], da: &[bool], db: &[bool]) -> f64 {
    let hits = a.iter().zip(db).filter(|(x, y)| **x && **y).count()
        + b.iter().zip(da).filter(|(x, y)| **x && **y).count();
    let total = a.iter().filter(|v| **v).count() + b.iter().filter(|v| **v).count();
    if total == 0 {
        1.0
    } else {
        hits as f64 / total as f64
    }
}

/// `a` grown by one pixel in every direction (3×3 neighbourhood) on an `n × n` grid.
fn dilate(a: &[bool], n: usize) -> Vec<bool> {
    let mut out = vec![false; a.len()];
    for y in 0..n {
        for x in 0..n {
            if a[y * n + x] {
                for yy in y.saturating_sub(1)..(y + 2).min(n) {
                    for xx in x.saturating_sub(1)..(x + 2).min(n) {
                        out[yy * n + xx] = true;
                    }
                }
            }
        }
    }
    out
}

/// Share of covered pixels of either mask with a covered pixel of the other within one
/// pixel: `(|A ∩ dil B| + |B ∩ dil A|) / (|A| + |B|)`, 1 for equal masks. A plain IoU of
/// thin attractors punishes sub-pixel differences: a right fit of the Sierpiński triangle,
/// scales within 0.001, scored 0.7–0.85 at 64²–128².
pub fn tolerant_agreement(a: &[bool], b: &[bool], n: usize) -> f64 {
    agreement_of(a, b, &dilate(a, n), &dilate(b, n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agreement_forgives_one_pixel_and_not_two() {
        let n = 8;
        let mut a = vec![false; n * n];
        a[3 * n + 3] = true;
        let mut b = vec![false; n * n];
        b[3 * n + 4] = true;
        assert_eq!(tolerant_agreement(&a, &a, n), 1.0);
        assert_eq!(tolerant_agreement(&a, &b, n), 1.0);
        let mut c = vec![false; n * n];
        c[3 * n + 5] = true;
        assert_eq!(tolerant_agreement(&a, &c, n), 0.0);
    }

    #[test]
    fn a_code_agrees_with_itself_in_2d_and_3d_and_not_with_another() {
        use ifslab_strategies::problems::em::EmModel;
        for (name, other) in [("sierpinski", "koch"), ("tetrahedron", "tetrahedron")] {
            let truth = Truth::load(name, resolve_code(name).unwrap().dim()).unwrap();
            let code = resolve_code(name).unwrap();
            let model = EmModel::from_code(&code, 6).unwrap();
            let a = truth.compare(&model).unwrap();
            assert!(a.agreement > 0.99 && a.iou > 0.9, "{name}: {a:?}");
            assert!(a.scale_error < 1e-9, "{name}: {a:?}");
            if other != name {
                let m = EmModel::from_code(&resolve_code(other).unwrap(), 6).unwrap();
                let b = truth.compare(&m).unwrap();
                assert!(b.agreement < 0.5, "{name} against {other}: {b:?}");
            }
        }
        // Three of the tetrahedron's four maps draw one face of it: not the tetrahedron.
        let mut code = resolve_code("tetrahedron").unwrap();
        code.maps.pop();
        code.probabilities = None;
        let truth = Truth::load("tetrahedron", 3).unwrap();
        let face = EmModel::from_code(&code, 6).unwrap();
        let c = truth.compare(&face).unwrap();
        assert!(c.agreement < 0.7 && c.scale_error.is_infinite(), "{c:?}");
    }
}
