//! How close a fitted code's attractor lies to the data it was fitted to, in both
//! directions: a score that needs no truth, so it can choose among a run's fits.
//!
//! The held-out likelihood scores a fit by its depth-D mixture of Gaussians; it can prefer
//! a fit whose leaves are spread wide over one whose attractor traces the cloud. The
//! closeness compares attractor and cloud as point sets: the distance from each data point
//! to the attractor (the cloud covered?) and from each attractor point to the data (nothing
//! drawn where the cloud is empty?), each a trimmed mean so that a cloud's outliers and the
//! sparse edges of a sample do not decide it.

use ifslab::metrics3d::nearest_distances;
use ifslab_strategies::problems::em::{EmModel, PointSet};
use serde::{Deserialize, Serialize};

use super::truth::attractor_points;

/// Attractor points drawn for the comparison.
const ATTRACTOR_POINTS: usize = 20_000;
/// Share of the data points (closest first) whose distance to the attractor is averaged:
/// a cloud's outliers (1 % in the robustness suite) are left out.
const DATA_KEPT: f64 = 0.95;
/// Share of the attractor points (closest first) whose distance to the data is averaged.
const ATTRACTOR_KEPT: f64 = 0.99;

/// The two directions of [`closeness`], in units of the data's RMS radius.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Closeness {
    /// Trimmed mean distance from a data point to the attractor.
    pub data_to_fit: f64,
    /// Trimmed mean distance from an attractor point to the data.
    pub fit_to_data: f64,
}

impl Closeness {
    /// The symmetric score: the mean of the two directions (lower is closer).
    pub fn chamfer(&self) -> f64 {
        0.5 * (self.data_to_fit + self.fit_to_data)
    }
}

/// Points of a set of up to three dimensions as 3-D points (the missing coordinates 0).
fn as_3d(flat: &[f64], dim: usize) -> Vec<[f64; 3]> {
    flat.chunks_exact(dim)
        .map(|p| std::array::from_fn(|k| p.get(k).copied().unwrap_or(0.0)))
        .collect()
}

/// The mean of the smallest `share` of `d` (at least one value).
fn trimmed_mean(mut d: Vec<f64>, share: f64) -> f64 {
    d.sort_by(f64::total_cmp);
    let n = ((d.len() as f64 * share).round() as usize).clamp(1, d.len());
    d[..n].iter().sum::<f64>() / n as f64
}

/// How close `model`'s attractor (drawn by the chaos game from `seed`) lies to `data`;
/// `None` for data of more than three dimensions (the nearest-point search is 3-D).
pub fn closeness(model: &EmModel, data: &PointSet, seed: u64) -> crate::Result<Option<Closeness>> {
    let dim = data.dim();
    if dim > 3 {
        return Ok(None);
    }
    let code = model.to_code(None)?;
    let fit = as_3d(&attractor_points(&code, ATTRACTOR_POINTS, seed)?, dim);
    let pts = as_3d(data.as_slice(), dim);
    let radius = data.rms_radius().max(1e-12);
    Ok(Some(Closeness {
        data_to_fit: trimmed_mean(nearest_distances(&pts, &fit)?, DATA_KEPT) / radius,
        fit_to_data: trimmed_mean(nearest_distances(&fit, &pts)?, ATTRACTOR_KEPT) / radius,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points of the built-in `name`'s attractor, with `outliers` far points added.
    fn cloud(name: &str, n: usize, outliers: usize) -> PointSet {
        let code = crate::codes::resolve_code(name).unwrap();
        let mut flat = attractor_points(&code, n, 7).unwrap();
        flat.truncate(2 * n);
        for i in 0..outliers {
            flat.extend([3.0 + i as f64 * 0.1, -2.0]);
        }
        PointSet::new(2, flat).unwrap()
    }

    #[test]
    fn the_true_code_is_closer_to_its_cloud_than_a_wrong_one_despite_outliers() {
        let data = cloud("sierpinski", 5000, 50);
        let truth =
            EmModel::from_code(&crate::codes::resolve_code("sierpinski").unwrap(), 6).unwrap();
        let mut wrong = truth.clone();
        wrong.components[0].s *= 0.8;
        let right = closeness(&truth, &data, 0).unwrap().unwrap();
        let off = closeness(&wrong, &data, 0).unwrap().unwrap();
        // 1 % of far outliers are trimmed away: the truth traces the rest.
        assert!(right.data_to_fit < 0.02, "{right:?}");
        assert!(right.chamfer() < off.chamfer(), "{right:?} against {off:?}");
        // Seeded: the same score twice.
        assert_eq!(Some(right), closeness(&truth, &data, 0).unwrap());
    }

    #[test]
    fn the_trimmed_mean_leaves_out_the_largest_values() {
        assert_eq!(trimmed_mean(vec![5.0, 1.0, 3.0, 100.0], 0.75), 3.0);
        assert_eq!(trimmed_mean(vec![2.0], 0.01), 2.0);
    }
}
