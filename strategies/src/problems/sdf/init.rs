//! Where the control points start.
//!
//! The paper: "I was able to consistently get optimization to converge by initializing the
//! control points p_i along a best-fit line of the black pixels in the target image." It does
//! not say where along the line. Our reading ([`SdfInit::Line`]): each point goes to the
//! place on the best-fit segment given by its projection on the pattern's base segment in the
//! pattern's own coordinates (Koch: 0, 1/3, 1/2, 2/3, 1), so the order of the points and
//! the spacing of the template are kept and only the shape is flattened.

use ifslab::model::segment::Pattern;
use ifslab::render::sdf::SdfView;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::problems::sdf::target::best_fit_line;

/// How the control points start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SdfInit {
    /// Along the best-fit line of the target's dark pixels (the paper's; see the module docs).
    #[default]
    Line,
    /// The pattern's own shape, placed so its base segment lies on the best-fit line.
    Pattern,
    /// The pattern's points as they are (a pattern file written in the target's frame).
    Given,
}

/// The starting θ (flat control points) for `pattern` on target `ink` seen through `view`,
/// with Gaussian noise of standard deviation `jitter` (plane units) drawn from `seed`.
pub fn initial_points(
    pattern: &Pattern,
    ink: &[f64],
    view: &SdfView,
    init: SdfInit,
    jitter: f64,
    seed: u64,
) -> Result<Vec<f64>> {
    let pts = pattern.points();
    let [a, b] = pattern.base_points();
    let mut theta: Vec<f64> = match init {
        SdfInit::Given => pattern.flat_points(),
        SdfInit::Line | SdfInit::Pattern => {
            let [l0, l1] = best_fit_line(ink, view)?;
            let e = [b[0] - a[0], b[1] - a[1]];
            let e2 = e[0] * e[0] + e[1] * e[1];
            let map = ifslab::model::segment::SegmentMap::between(a, b, l0, l1)
                .ok_or_else(|| Error::InvalidInput("the base segment has zero length".into()))?;
            pts.iter()
                .flat_map(|p| match init {
                    SdfInit::Line => {
                        let s = ((p[0] - a[0]) * e[0] + (p[1] - a[1]) * e[1]) / e2;
                        [l0[0] + s * (l1[0] - l0[0]), l0[1] + s * (l1[1] - l0[1])]
                    }
                    _ => ifslab::model::Map2::apply(&map, *p),
                })
                .collect()
        }
    };
    if jitter > 0.0 {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let n = Normal::new(0.0, jitter).map_err(|e| Error::param("jitter", format!("{e}")))?;
        for v in theta.iter_mut() {
            *v += n.sample(&mut rng);
        }
    }
    pattern.with_flat_points(&theta).map_err(|e| {
        Error::InvalidInput(format!(
            "the {init:?} start of pattern `{}` is unusable ({e}); try `init = \"pattern\"` or some `jitter`",
            pattern.name()
        ))
    })?;
    Ok(theta)
}
