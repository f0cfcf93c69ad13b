//! Loss landscapes of segment-map fits: the fit's loss on a 2-D slice of control-point space
//! through a set of points, on the shared grid of [`crate::problems::image::landscape`]
//! (random directions are filter-normalised per control point; coordinate directions move
//! raw θ entries, `2k` and `2k + 1` being control point k's x and y). The render is
//! deterministic, so one evaluation per grid point is exact whatever `streams` says.

use super::SdfProblem;
use crate::error::{Error, Result};
use crate::problems::image::landscape::{Landscape, LandscapeConfig, slice};

/// Samples the slice of `problem`'s loss through the flat control points `theta`; the
/// second grid holds the unweighted pixel term. `tick` is called once per grid point.
pub fn sdf_landscape(
    problem: &SdfProblem,
    theta: &[f64],
    cfg: &LandscapeConfig,
    tick: &(dyn Fn() + Sync),
) -> Result<Landscape> {
    if problem.learned().is_some() {
        return Err(Error::InvalidInput(
            "the landscape of a learned-pattern fit is not supported (θ holds pair logits)".into(),
        ));
    }
    let points = problem.pattern().points().len();
    if theta.len() != 2 * points {
        return Err(Error::InvalidInput(format!(
            "θ has {} values, the pattern has {points} control points ({} values)",
            theta.len(),
            2 * points
        )));
    }
    let cfg = LandscapeConfig {
        streams: 1,
        ..cfg.clone()
    };
    let eval = |th: &[f64], _stream: u64| -> Result<(f64, f64)> {
        let e = problem.eval(th, false)?;
        Ok((e.loss, e.pixel))
    };
    slice(theta, 2, &cfg, &eval, tick)
}
