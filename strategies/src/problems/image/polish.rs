//! The IoU polish: after the image fit, the code's maps are moved to raise the IoU of their
//! attractor with the picture's ink, read at a finer size than the fit's target.
//!
//! The fit's loss compares splat renders with the framed target at `target.size` (128 by
//! default): a picture reduced or enlarged into it is thickened and greyed, and started from
//! the true code the fit leaves it to match that copy better (robustness/README.md, "What is
//! left"). The polish judges a code the way a shape is compared: the pixels its attractor
//! touches against the ink, at [`Polish::size`], with the attractor drawn a little wider where
//! the picture's strokes are wider than a pixel (the widening that scores the fitted code
//! best at the polish's start is kept throughout, so a thick-lined picture is not met by
//! fattening the maps).
//!
//! The search is a (1 + λ) evolution strategy on common random numbers (every proposal's
//! attractor drawn from the same seeded chaos game, so a proposal wins on its maps, not on
//! its draw): each round, λ proposals each move one map (Gaussian steps on its matrix and
//! offset, singular values kept in a contractive range) or the whole code (a small
//! similarity about the ink's centre: the registration of the code to the picture), the best
//! is taken if it scores at least the current code, and each kind's step grows on success and
//! shrinks otherwise. The proposals of a round are drawn from the round's own stream and scored
//! in parallel, the best chosen by index on ties: the result depends on the seed only. A
//! polished code is kept only where it also scores higher on a second, independent draw.

use ifslab::chaos::{mix_seed, trajectory_rng};
use ifslab::model::Affine2;
use nalgebra::{Matrix2, Vector2};
use rand::Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;

use crate::error::Result;
use crate::problems::image::collage::{
    Field, PixelMap, attractor_points, clamp_singular_values, to_inversion_frame,
};

/// Settings of the polish.
#[derive(Clone, Debug, PartialEq)]
pub struct Polish {
    /// Rounds of the evolution strategy (0: no polish).
    pub rounds: usize,
    /// Proposals scored per round.
    pub proposals: usize,
    /// A pixel is ink from this share of the brightest pixel on (as the collage start reads it).
    pub ink_level: f64,
    /// Attractor points per score at a 128-pixel field (scaled with the field's area).
    pub points: usize,
    /// Widenings of the attractor's pixels tried at the start (disc radii in pixels).
    pub radii: [f64; 4],
    /// Range of a map's singular values.
    pub scales: (f64, f64),
}

impl Default for Polish {
    fn default() -> Self {
        Polish {
            rounds: 0,
            proposals: 8,
            ink_level: 0.2,
            points: 60_000,
            radii: [0.0, 1.0, 1.5, 2.5],
            scales: (0.01, 0.95),
        }
    }
}

/// What the polish did.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Polished {
    /// The maps it returns, in the inversion's coordinates of the field (`[−1, 1]²`): the
    /// fitted maps framed onto the ink, polished where that scored higher on the check draw
    /// (not in the summary: the code file holds them).
    #[serde(skip)]
    pub maps: Vec<Affine2>,
    /// IoU with the ink of the fitted maps (framed onto the ink) and of the polished ones, on
    /// the search's draw.
    pub iou: [f64; 2],
    /// The same on the independent check draw.
    pub check: [f64; 2],
    /// Whether the polished maps were kept.
    pub kept: bool,
    /// The widening of the attractor's pixels (disc radius in pixels).
    pub radius: f64,
    /// Rounds whose best proposal was taken.
    pub accepted: usize,
}

/// The field's pixels whose centre lies within `radius` of a pixel that one of `points`
/// falls in.
fn raster(points: &[Vector2<f64>], size: usize, offsets: &[(i64, i64)]) -> Vec<bool> {
    let s = size as i64;
    let mut hit = vec![false; size * size];
    for q in points {
        let (x, y) = (q[0].floor() as i64, q[1].floor() as i64);
        if (0..s).contains(&x) && (0..s).contains(&y) {
            hit[(y * s + x) as usize] = true;
        }
    }
    if offsets.len() == 1 {
        return hit;
    }
    let mut wide = vec![false; size * size];
    for (i, _) in hit.iter().enumerate().filter(|(_, h)| **h) {
        let (x, y) = ((i % size) as i64, (i / size) as i64);
        for &(dx, dy) in offsets {
            let (u, v) = (x + dx, y + dy);
            if (0..s).contains(&u) && (0..s).contains(&v) {
                wide[(v * s + u) as usize] = true;
            }
        }
    }
    wide
}

/// The pixel offsets within a disc of `radius`.
fn disc(radius: f64) -> Vec<(i64, i64)> {
    let r = radius.floor() as i64;
    (-r..=r)
        .flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)))
        .filter(|&(dx, dy)| ((dx * dx + dy * dy) as f64) <= radius * radius + 1e-9)
        .collect()
}

fn iou(a: &[bool], b: &[bool]) -> f64 {
    let (mut both, mut either) = (0usize, 0usize);
    for (&x, &y) in a.iter().zip(b) {
        both += (x && y) as usize;
        either += (x || y) as usize;
    }
    both as f64 / either.max(1) as f64
}

/// `maps` conjugated by `x ↦ L·x + t`: the code whose attractor is the image of theirs.
fn conjugate(maps: &[PixelMap], l: &Matrix2<f64>, t: &Vector2<f64>) -> Vec<PixelMap> {
    let Some(inv) = l.try_inverse() else {
        return maps.to_vec();
    };
    maps.iter()
        .map(|m| {
            let g = l * m.g * inv;
            PixelMap {
                g,
                h: l * m.h + t - g * t,
            }
        })
        .collect()
}

/// The bounding box of the centres of the ink pixels, widened by half a pixel: `(lo, hi)`.
fn ink_box(field: &Field) -> (Vector2<f64>, Vector2<f64>) {
    let mut lo = Vector2::repeat(f64::INFINITY);
    let mut hi = Vector2::repeat(f64::NEG_INFINITY);
    for p in &field.points {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    (lo.add_scalar(-0.5), hi.add_scalar(0.5))
}

/// `maps` (any coordinates) in the field's pixel frame, their attractor's bounding box
/// centred on the ink's and scaled so its longer side spans the ink's (the splat's framing),
/// y pointing down.
fn framed_onto_ink(field: &Field, maps: &[Affine2], seed: u64) -> Option<Vec<PixelMap>> {
    let world: Vec<PixelMap> = maps.iter().map(|m| PixelMap { g: m.m, h: m.b }).collect();
    let pts = attractor_points(&world, 20_000, seed)?;
    let mut lo = Vector2::repeat(f64::INFINITY);
    let mut hi = Vector2::repeat(f64::NEG_INFINITY);
    for p in &pts {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let (ilo, ihi) = ink_box(field);
    let span = (hi - lo).amax();
    if !(span.is_finite() && span > 0.0) {
        return None;
    }
    let k = (ihi - ilo).amax() / span;
    let l = Matrix2::new(k, 0.0, 0.0, -k);
    let t = 0.5 * (ilo + ihi) - l * (0.5 * (lo + hi));
    Some(conjugate(&world, &l, &t))
}

/// Polishes `maps` against the ink of `target` (`size × size`, row 0 at the top); see the
/// module's description. Deterministic for `seed`. `None` when the maps have no drawable
/// attractor (every map degenerate).
pub fn polish(
    target: &[f32],
    size: usize,
    maps: &[Affine2],
    seed: u64,
    settings: &Polish,
) -> Result<Option<Polished>> {
    let field = Field::new(target, size, settings.ink_level)?;
    let stream = mix_seed(seed, 0x9011_5400);
    let Some(start) = framed_onto_ink(&field, maps, mix_seed(stream, 1)) else {
        return Ok(None);
    };
    let points = (settings.points as f64 * (size as f64 / 128.0).powi(2)).round() as usize;
    let (search_seed, check_seed) = (mix_seed(stream, 2), mix_seed(stream, 3));
    let score = |m: &[PixelMap], offsets: &[(i64, i64)], seed: u64| -> f64 {
        attractor_points(m, points, seed)
            .map_or(0.0, |p| iou(&raster(&p, size, offsets), &field.ink))
    };
    // The widening that scores the fitted code best.
    let (mut offsets, mut radius, mut current) = (disc(0.0), 0.0, f64::NEG_INFINITY);
    for &r in &settings.radii {
        let o = disc(r);
        let v = score(&start, &o, search_seed);
        if v > current {
            (offsets, radius, current) = (o, r, v);
        }
    }
    let before = current;
    let mut code = start.clone();
    // Steps: a map's matrix entries, its offset (pixels), and the whole code's similarity
    // (scale and angle; its shift is the offset step).
    let (mut step_map, mut step_all) = (1.0f64, 1.0f64);
    let (sg, sh) = (0.02, 0.004 * size as f64);
    let centre = {
        let (lo, hi) = ink_box(&field);
        0.5 * (lo + hi)
    };
    let mut accepted = 0;
    for round in 0..settings.rounds {
        let proposals: Vec<(bool, Vec<PixelMap>)> = (0..settings.proposals)
            .map(|j| {
                let mut rng = trajectory_rng(mix_seed(stream, 10 + round as u64), j as u64);
                let mut n = || rng.sample::<f64, _>(StandardNormal);
                let global = j % 4 == 3;
                if global {
                    let (a, s) = (0.01 * step_all * n(), 1.0 + 0.01 * step_all * n());
                    let l = s * Matrix2::new(a.cos(), -a.sin(), a.sin(), a.cos());
                    let shift = Vector2::new(n(), n()) * sh * step_all;
                    let t = centre + shift - l * centre;
                    (true, conjugate(&code, &l, &t))
                } else {
                    let mut c = code.clone();
                    let i = (n().abs() * 1e6) as usize % c.len();
                    let d = Matrix2::new(n(), n(), n(), n()) * sg * step_map;
                    c[i].g = clamp_singular_values(&(c[i].g + d), settings.scales);
                    c[i].h += Vector2::new(n(), n()) * sh * step_map;
                    (false, c)
                }
            })
            .collect();
        let scores: Vec<f64> = proposals
            .par_iter()
            .map(|(_, c)| score(c, &offsets, search_seed))
            .collect();
        let mut best: Option<usize> = None;
        for (j, v) in scores.iter().enumerate() {
            if best.is_none_or(|b| *v > scores[b]) {
                best = Some(j);
            }
        }
        let Some(b) = best else { break };
        let global = proposals[b].0;
        let grow = |s: &mut f64, ok: bool| *s = (*s * if ok { 1.3 } else { 0.93 }).clamp(0.05, 4.0);
        if scores[b] >= current {
            current = scores[b];
            code = proposals[b].1.clone();
            accepted += 1;
            grow(if global { &mut step_all } else { &mut step_map }, true);
        } else {
            grow(&mut step_map, false);
            grow(&mut step_all, false);
        }
    }
    let check = [
        score(&start, &offsets, check_seed),
        score(&code, &offsets, check_seed),
    ];
    let kept = check[1] > check[0];
    let chosen = if kept { &code } else { &start };
    Ok(Some(Polished {
        maps: chosen.iter().map(|m| to_inversion_frame(m, size)).collect(),
        iou: [before, current],
        check,
        kept,
        radius,
        accepted,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use ifslab::model::library;
    use ifslab::render::{RenderConfig, render};

    /// The ink of `maps`' attractor drawn by the evaluation renderer at `size²`.
    fn picture(maps: &[Affine2], size: usize) -> Vec<f32> {
        let code = ifslab::model::IfsCode::from_affine2(None, maps).unwrap();
        render(
            maps,
            &code.evaluation_probabilities().unwrap(),
            &RenderConfig {
                width: size as u32,
                height: size as u32,
                points: 400_000,
                supersample: 2,
                ..RenderConfig::default()
            },
            None,
        )
        .unwrap()
        .image
        .values
    }

    /// A Sierpiński code with its maps moved polishes back towards the picture of the
    /// true one, the same on one thread as on two.
    #[test]
    fn a_perturbed_code_is_polished_towards_the_picture() {
        let size = 128;
        let truth = library::builtin("sierpinski").unwrap().affine2().unwrap();
        let target = picture(&truth, size);
        let mut off = truth.clone();
        off[0].m[(0, 0)] *= 0.85;
        off[1].b[0] += 0.06;
        off[2].m[(1, 0)] += 0.08;
        let settings = Polish {
            rounds: 150,
            ..Polish::default()
        };
        let p = polish(&target, size, &off, 3, &settings).unwrap().unwrap();
        assert!(p.kept, "{p:?}");
        assert!(p.check[1] > p.check[0] + 0.1, "{p:?}");
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| polish(&target, size, &off, 3, &settings).unwrap().unwrap());
        assert_eq!(one, p);
        // The truth itself is kept as it is (framed onto the ink).
        let t = polish(&target, size, &truth, 3, &settings)
            .unwrap()
            .unwrap();
        assert!(t.iou[0] > 0.6 && t.iou[1] - t.iou[0] < 0.1, "{t:?}");
    }

    /// A thick-lined picture is met by widening the attractor's pixels, not by fattening
    /// the maps.
    #[test]
    fn a_thick_picture_is_read_with_a_wider_attractor() {
        let size = 128;
        let truth = library::builtin("sierpinski").unwrap().affine2().unwrap();
        let thin = picture(&truth, size);
        let ink: Vec<bool> = thin.iter().map(|&v| v > 0.1).collect();
        let thick: Vec<f32> = (0..size * size)
            .map(|i| {
                let (x, y) = ((i % size) as i64, (i / size) as i64);
                let near = (-2..=2).any(|dy: i64| {
                    (-2..=2).any(|dx: i64| {
                        let (u, v) = (x + dx, y + dy);
                        dx * dx + dy * dy <= 4
                            && (0..size as i64).contains(&u)
                            && (0..size as i64).contains(&v)
                            && ink[(v * size as i64 + u) as usize]
                    })
                });
                near as u8 as f32
            })
            .collect();
        let p = polish(
            &thick,
            size,
            &truth,
            0,
            &Polish {
                rounds: 20,
                ..Polish::default()
            },
        )
        .unwrap()
        .unwrap();
        assert!(p.radius >= 1.5, "{p:?}");
    }
}
