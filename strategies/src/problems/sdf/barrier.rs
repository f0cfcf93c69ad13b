//! A barrier on the maps' scales: `Σᵢ max(0, sᵢ − s_max)²` over the maps of a pattern,
//! `sᵢ = |wᵢ|` the scale of the similitude pair `i` defines.
//!
//! An optimiser may pass through patterns whose maps stop contracting (the renderer draws
//! them to a finite depth all the same); fitted to a filled shape, the Koch pattern's maps
//! grow past 1, since at a finite depth a larger copy covers more (measured in
//! `paper_repro/differentiable_ifs/`). The barrier is zero while every scale stays below
//! `s_max` and pulls the ones above it back, so the fit's result is an IFS. With learned
//! pairs it also replaces the refusal of soft maps that expand.

use ifslab::model::segment::{Pattern, SegmentMap};

use crate::error::{Error, Result};

/// The barrier of `pattern`'s maps above `max_scale`, and its gradient with respect to the
/// pattern's points (flat `[x₀, y₀, …]`, as the renderer's gradient).
pub fn scale_barrier(pattern: &Pattern, max_scale: f64) -> Result<(f64, Vec<f64>)> {
    let pts = pattern.points();
    let mut g = vec![0.0; 2 * pts.len()];
    let mut v = 0.0;
    for (i, pr) in pattern.pairs().iter().enumerate() {
        let [e1, e2] = pr.source.map(|k| pts[k]);
        let [p1, p2] = pr.target.map(|k| pts[k]);
        let m = SegmentMap::between(e1, e2, p1, p2).ok_or_else(|| {
            Error::Numerical(format!("pair {i}: the source segment has zero length"))
        })?;
        let s = m.scale();
        let over = s - max_scale;
        if over <= 0.0 {
            continue;
        }
        v += over * over;
        // ∂s/∂w = w/|w| (w as [re, im]); the translation does not enter.
        let gw = [2.0 * over * m.w[0] / s, 2.0 * over * m.w[1] / s];
        let ge = SegmentMap::between_backward(e1, e2, p1, p2, gw, [0.0, 0.0]);
        for (k, gk) in [pr.source[0], pr.source[1], pr.target[0], pr.target[1]]
            .into_iter()
            .zip(ge)
        {
            g[2 * k] += gk[0];
            g[2 * k + 1] += gk[1];
        }
    }
    Ok((v, g))
}
