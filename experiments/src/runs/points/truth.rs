//! Comparing a fit with the code that made the data (2-D): the agreement of the two
//! attractors' coverage and the largest difference of their sorted scales, since a run can
//! meet the convergence criterion with a wrong code.

use anyhow::{Context, bail};
use ifslab::model::IfsCode;
use ifslab::render::{RenderConfig, RenderMode, View, render};
use ifslab_strategies::problems::em::EmModel;

use crate::codes::resolve_code;

/// A fit counts as right when its coverage agreement with the truth reaches this.
pub const RIGHT_AGREEMENT: f64 = 0.9;

/// Side of the coverage masks compared with the truth.
pub const TRUTH_SIZE: u32 = 128;
/// Points per coverage render.
const TRUTH_POINTS: u64 = 2_000_000;

/// The code that made the data: its sorted scales and its coverage mask in the window its
/// attractor fills.
pub struct Truth {
    scales: Vec<f64>,
    window: View,
    mask: Vec<bool>,
}

/// How one fit compares with the truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Against {
    /// Coverage agreement ([`tolerant_agreement`]), 1 for equal attractors.
    pub agreement: f64,
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
fn coverage(code: &IfsCode, view: View, seed: u64) -> anyhow::Result<(Vec<bool>, View)> {
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

impl Truth {
    /// The truth named by `spec` (a code file or a built-in name) for data of dimension
    /// `dim`; both must be 2-D and every map a similitude with a proper rotation.
    pub fn load(spec: &str, dim: usize) -> anyhow::Result<Truth> {
        let code = resolve_code(spec).with_context(|| format!("`truth` {spec}"))?;
        if code.dim() != 2 || dim != 2 {
            bail!(
                "`truth` compares 2-D attractors; the code is {}-D and the data {dim}-D",
                code.dim()
            );
        }
        let mut scales = Vec::new();
        for (i, m) in code.maps.iter().enumerate() {
            let d = m.m.determinant();
            if d.is_nan() || d <= 0.0 {
                bail!("`truth` {spec}: map {i} is not a similitude with a proper rotation");
            }
            scales.push(d.sqrt());
        }
        scales.sort_by(f64::total_cmp);
        let (mask, window) = coverage(&code, View::Fit, 0)?;
        Ok(Truth {
            scales,
            window,
            mask,
        })
    }

    /// How a fitted model compares with the truth.
    pub fn compare(&self, model: &EmModel) -> anyhow::Result<Against> {
        let code = model.to_code(None)?;
        let (mask, _) = coverage(&code, self.window, 0)?;
        let agreement = tolerant_agreement(&self.mask, &mask, TRUTH_SIZE as usize);
        let mut scales: Vec<f64> = model.components.iter().map(|c| c.s).collect();
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
            scale_error,
        })
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
    let (da, db) = (dilate(a, n), dilate(b, n));
    let hits = a.iter().zip(&db).filter(|(x, y)| **x && **y).count()
        + b.iter().zip(&da).filter(|(x, y)| **x && **y).count();
    let total = a.iter().filter(|v| **v).count() + b.iter().filter(|v| **v).count();
    if total == 0 {
        1.0
    } else {
        hits as f64 / total as f64
    }
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
}
