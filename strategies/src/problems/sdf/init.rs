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
use crate::problems::sdf::target::{INK, best_fit_line};

/// Adam steps each candidate of [`SdfInit::Best`] is followed for (at the schedule's first,
/// widest σ) before they are compared (`best_start` in `run.rs`); the default of
/// `init.probe_steps`. 80 rather than 40: on the robustness suite's tuning splits a Koch
/// curve drawn with one-pixel lines picked the wrong start after 40 steps (truth IoU 0.49)
/// and the right one after 80 (0.96); 80, 120 and 300 changed nothing else.
pub const PROBE_STEPS: u64 = 80;

/// The least ratio of the ink box's aspect to the pattern's at which [`candidate_starts`]
/// adds the pattern stretched into the ink's box.
pub const STRETCH_MIN_RATIO: f64 = 1.05;

/// The largest such ratio: beyond it the pattern's box is too unlike the ink's to stretch.
pub const STRETCH_MAX_RATIO: f64 = 4.0;

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
    /// The best of several starts ([`candidate_starts`]: the line, the pattern on the line
    /// either way up, the pattern in the ink's box either way up, with its aspect kept and
    /// stretched to fill the box), each followed for a few coarse steps; the one whose loss
    /// is lowest after them starts the fit.
    Best,
}

impl SdfInit {
    /// Its name in configs.
    pub fn name(&self) -> &'static str {
        match self {
            SdfInit::Line => "line",
            SdfInit::Pattern => "pattern",
            SdfInit::Given => "given",
            SdfInit::Best => "best",
        }
    }
}

/// The starts [`SdfInit::Best`] chooses from, by name: `line` (the paper's), `pattern` (its
/// own shape with its base on the best-fit line), `pattern_flipped` (the same mirrored across
/// the line: a bump the other way), `box` (the pattern's bounding box fitted into the ink's,
/// its aspect kept) and `box_flipped` (mirrored left to right), and with `stretched`
/// `box_stretched` and `box_stretched_flipped` (the box filled on both axes, where the
/// aspects differ). Starts the pattern cannot take (a map that
/// stops contracting) are left out.
pub fn candidate_starts(
    pattern: &Pattern,
    ink: &[f64],
    view: &SdfView,
    stretched: bool,
) -> Result<Vec<(&'static str, Vec<f64>)>> {
    let mut out = Vec::new();
    let mut push = |name: &'static str, theta: Vec<f64>| {
        if pattern.with_flat_points(&theta).is_ok() {
            out.push((name, theta));
        }
    };
    push(
        "line",
        initial_points(pattern, ink, view, SdfInit::Line, 0.0, 0)?,
    );
    let on_line = initial_points(pattern, ink, view, SdfInit::Pattern, 0.0, 0)?;
    let [l0, l1] = best_fit_line(ink, view)?;
    push("pattern_flipped", mirror_across(&on_line, l0, l1));
    push("pattern", on_line);
    // The ink's box and the pattern's, centre to centre, the pattern scaled to fit.
    let (lo, hi) = ink_box(ink, view)?;
    let pts = pattern.points();
    let (plo, phi) = pts
        .iter()
        .fold(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]), |(l, h), p| {
            (
                [l[0].min(p[0]), l[1].min(p[1])],
                [h[0].max(p[0]), h[1].max(p[1])],
            )
        });
    let per_axis = [
        (hi[0] - lo[0]) / (phi[0] - plo[0]).max(1e-12),
        (hi[1] - lo[1]) / (phi[1] - plo[1]).max(1e-12),
    ];
    let scale = per_axis[0].min(per_axis[1]);
    let (c, pc) = (
        [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])],
        [0.5 * (plo[0] + phi[0]), 0.5 * (plo[1] + phi[1])],
    );
    let placed = |s: [f64; 2], flip: f64| -> Vec<f64> {
        pts.iter()
            .flat_map(|p| {
                [
                    c[0] + flip * s[0] * (p[0] - pc[0]),
                    c[1] + s[1] * (p[1] - pc[1]),
                ]
            })
            .collect()
    };
    if scale.is_finite() && scale > 0.0 {
        for (name, flip) in [("box", 1.0), ("box_flipped", -1.0)] {
            push(name, placed([scale; 2], flip));
        }
    }
    // The pattern stretched to fill the ink's box on both axes: a Koch curve whose apex is
    // lower or higher than the template's spans the ink's width only this way (the box start
    // above, its aspect kept, starts it contracted, and a thin curve's fit stays so). Only
    // where the aspects differ by more than STRETCH_MIN_RATIO, and by no more than
    // STRETCH_MAX_RATIO (a line-like pattern's box is no shape to stretch).
    let ratio = per_axis[0].max(per_axis[1]) / scale;
    if stretched
        && scale.is_finite()
        && scale > 0.0
        && per_axis.iter().all(|s| s.is_finite())
        && ratio > STRETCH_MIN_RATIO
        && ratio <= STRETCH_MAX_RATIO
    {
        for (name, flip) in [("box_stretched", 1.0), ("box_stretched_flipped", -1.0)] {
            push(name, placed(per_axis, flip));
        }
    }
    Ok(out)
}

/// Flat points mirrored across the line through `a` and `b`.
fn mirror_across(theta: &[f64], a: [f64; 2], b: [f64; 2]) -> Vec<f64> {
    let d = [b[0] - a[0], b[1] - a[1]];
    let n2 = (d[0] * d[0] + d[1] * d[1]).max(1e-300);
    theta
        .chunks_exact(2)
        .flat_map(|p| {
            let v = [p[0] - a[0], p[1] - a[1]];
            let t = (v[0] * d[0] + v[1] * d[1]) / n2;
            let foot = [a[0] + t * d[0], a[1] + t * d[1]];
            [2.0 * foot[0] - p[0], 2.0 * foot[1] - p[1]]
        })
        .collect()
}

/// The box of the pixel centres with ink ≥ [`INK`], in the plane of `view`.
fn ink_box(ink: &[f64], view: &SdfView) -> Result<([f64; 2], [f64; 2])> {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for i in 0..view.height {
        for j in 0..view.width {
            if ink[i * view.width + j] >= INK {
                let c = view.centre(i, j);
                lo = [lo[0].min(c[0]), lo[1].min(c[1])];
                hi = [hi[0].max(c[0]), hi[1].max(c[1])];
            }
        }
    }
    if lo[0] > hi[0] {
        return Err(Error::InvalidInput(format!(
            "the target has no pixel with ink ≥ {INK}"
        )));
    }
    Ok((lo, hi))
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
        SdfInit::Best => {
            return Err(Error::InvalidInput(
                "the best of several starts is chosen by the fit (`run_sdf`), which follows \
                 each for a few steps"
                    .into(),
            ));
        }
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
                    _ => ifslab::model::Map::apply(&map, *p),
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
