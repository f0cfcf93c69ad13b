//! The collage start: an IFS assembled from affine copies of the target found inside the
//! target itself (Barnsley's collage theorem: a code whose maps carry the attractor A into
//! pieces that cover A has an attractor close to A).
//!
//! The EM start fits similitudes to the target's point density; on random affine codes it
//! covers the right area with pieces in the wrong arrangement, a basin the image loss does not
//! leave (`robustness/README.md` measures it: started from the true code the loss is a third
//! of every EM start's). This search looks for the arrangement directly:
//!
//! 1. **Candidate maps.** From many random affine starts, each map `g` is moved by Adam to
//!    minimise `mean_x D(g(x)) − λ·log|det g|` over points `x` of the ink, `D` the distance
//!    (in pixels) to the nearest ink pixel: the image of the target must lie on the target
//!    (containment), as large as possible. Singular values stay in
//!    [`CollageSearch::scales`]. A candidate is kept when a share
//!    [`CollageSearch::containment`] of its image lies within one pixel of the ink.
//! 2. **Covers.** The candidates that together cover the most ink are chosen greedily, `k`
//!    of them (a deterministic pass, then randomised passes that weigh each gain by a
//!    random factor).
//! 3. **Refinement** (optional: [`CollageSearch::refine`] rounds, `model.collage_refine`;
//!    off by default, robustness/README.md measures it). Each cover's maps are moved together towards an exact
//!    collage by a symmetric closest-point fit: copies' points off the ink are pulled to the
//!    ink, ink pixels pull the nearest copied point, each map is the least-squares fit of
//!    its pairs. The refined cover competes with its unrefined self in the selection.
//! 4. **Selection.** Each cover is scored by the IoU of its own attractor (chaos game,
//!    probabilities ∝ |det| with the evaluation renders' 1 % floor) against the ink; the best
//!    is the start.
//!
//! Every candidate draws from its own seeded stream and the reductions run in index order,
//! so the result depends on the seed only, not on the thread count. [`init`] lets the EM
//! start compete on the same score (`collage_or_em`).
//!
//! ## References
//! - M. F. Barnsley, V. Ervin, D. Hardin and J. Lancaster, *Solution of an inverse problem
//!   for fractals and other sets*, PNAS 83(7), 1986 (the collage theorem).
//! - P. Felzenszwalb and D. Huttenlocher, *Distance transforms of sampled functions*,
//!   Theory of Computing 8, 2012 (the distance to the ink, `ifslab::image::distance_to`).
//!
//! [`init`]: crate::problems::image::init

use ifslab::chaos::{MapSampler, Trajectory, mix_seed, trajectory_rng};
use ifslab::model::{Affine2, ProbabilityRule};
use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, DimDiff, DimMin, DimSub, Matrix2, OMatrix, U1, Vector2};
use rand::Rng;
use rayon::prelude::*;

use crate::error::{Error, Result};

/// Settings of the collage search (the defaults were chosen on the robustness suite's tuning
/// split, `robustness/README.md`).
#[derive(Clone, Debug, PartialEq)]
pub struct CollageSearch {
    /// A pixel is ink from this share of the brightest pixel on (a fifth: the grey edges of
    /// thin anti-aliased strokes count; half lost them and scored 0.49 against 0.59 at the
    /// start on the tuning split).
    pub ink_level: f64,
    /// Random starts of the candidate search.
    pub candidates: usize,
    /// Adam steps per candidate.
    pub steps: usize,
    /// Ink points per candidate's objective.
    pub batch: usize,
    /// λ, the reward for a map's area, in pixels of distance per unit of `log|det|` at a
    /// 128-pixel target (scaled with the target's size).
    pub area_weight: f64,
    /// Share of a candidate's image that must lie within one pixel of the ink.
    pub containment: f64,
    /// Greedy covers scored (the first deterministic).
    pub covers: usize,
    /// Range of a map's singular values.
    pub scales: (f64, f64),
    /// Chaos-game points of the attractor that scores a cover.
    pub score_points: usize,
    /// Rounds of [`refine_cover`] applied to each cover before it is scored (0: off); a
    /// refined cover competes with its unrefined self.
    pub refine: usize,
}

impl Default for CollageSearch {
    fn default() -> Self {
        CollageSearch {
            ink_level: 0.2,
            candidates: 600,
            steps: 150,
            batch: 400,
            area_weight: 0.1,
            containment: 0.9,
            covers: 10,
            scales: (0.02, 0.9),
            score_points: 60_000,
            refine: 0,
        }
    }
}

/// A map in pixel coordinates (x right, y down, pixel centres at `i + ½`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PixelMap {
    pub(crate) g: Matrix2<f64>,
    pub(crate) h: Vector2<f64>,
}

impl PixelMap {
    fn apply(&self, p: &Vector2<f64>) -> Vector2<f64> {
        self.g * p + self.h
    }
}

/// The target as the search sees it: its ink mask, the distance to the ink and its
/// gradient, and the ink pixels' centres.
pub(crate) struct Field {
    size: usize,
    pub(crate) ink: Vec<bool>,
    dist: Vec<f32>,
    grad: Vec<[f32; 2]>,
    /// The ink pixels' centres.
    pub(crate) points: Vec<Vector2<f64>>,
}

impl Field {
    pub(crate) fn new(target: &[f32], size: usize, ink_level: f64) -> Result<Field> {
        let max = target.iter().copied().fold(0.0f32, f32::max);
        if max.is_nan() || max <= 0.0 {
            return Err(Error::InvalidInput(
                "the target has no bright pixels for the collage start".into(),
            ));
        }
        let level = ink_level as f32 * max;
        let ink: Vec<bool> = target.iter().map(|&v| v >= level).collect();
        let points: Vec<Vector2<f64>> = ink
            .iter()
            .enumerate()
            .filter(|(_, on)| **on)
            .map(|(i, _)| Vector2::new((i % size) as f64 + 0.5, (i / size) as f64 + 0.5))
            .collect();
        if points.len() < 8 {
            return Err(Error::InvalidInput(format!(
                "the target has {} ink pixel(s); the collage start needs at least 8",
                points.len()
            )));
        }
        let dist: Vec<f32> = ifslab::image::distance_to(&ink, size, size)
            .expect("the ink has pixels")
            .into_iter()
            .map(|d| d as f32)
            .collect();
        let at = |x: usize, y: usize| dist[y * size + x];
        let mut grad = vec![[0.0f32; 2]; size * size];
        for y in 0..size {
            for x in 0..size {
                let (x0, x1) = (x.saturating_sub(1), (x + 1).min(size - 1));
                let (y0, y1) = (y.saturating_sub(1), (y + 1).min(size - 1));
                grad[y * size + x] = [
                    (at(x1, y) - at(x0, y)) / (x1 - x0).max(1) as f32,
                    (at(x, y1) - at(x, y0)) / (y1 - y0).max(1) as f32,
                ];
            }
        }
        Ok(Field {
            size,
            ink,
            dist,
            grad,
            points,
        })
    }

    /// Distance to the ink at `p` (bilinear between pixel centres; outside the canvas, plus
    /// the distance to it) and its gradient.
    fn sample(&self, p: &Vector2<f64>) -> (f64, Vector2<f64>) {
        let s = self.size;
        let hi = s as f64 - 1.0;
        let (qx, qy) = (p[0] - 0.5, p[1] - 0.5);
        let (cx, cy) = (qx.clamp(0.0, hi), qy.clamp(0.0, hi));
        let (ox, oy) = (qx - cx, qy - cy);
        let i0 = (cx.floor() as usize).min(s.saturating_sub(2));
        let j0 = (cy.floor() as usize).min(s.saturating_sub(2));
        let (fx, fy) = (cx - i0 as f64, cy - j0 as f64);
        let (i1, j1) = ((i0 + 1).min(s - 1), (j0 + 1).min(s - 1));
        let w = [
            (1.0 - fx) * (1.0 - fy),
            fx * (1.0 - fy),
            (1.0 - fx) * fy,
            fx * fy,
        ];
        let idx = [j0 * s + i0, j0 * s + i1, j1 * s + i0, j1 * s + i1];
        let mut d = 0.0;
        let mut g = Vector2::zeros();
        for (w, i) in w.iter().zip(idx) {
            d += w * self.dist[i] as f64;
            g[0] += w * self.grad[i][0] as f64;
            g[1] += w * self.grad[i][1] as f64;
        }
        // Outside the canvas: the distance to it, pulling the point back in.
        d += ox.abs() + oy.abs();
        g[0] += ox.signum() * (ox != 0.0) as u8 as f64;
        g[1] += oy.signum() * (oy != 0.0) as u8 as f64;
        (d, g)
    }

    /// The ink pixels within one pixel of `map`'s image of the ink, as a bit set.
    fn coverage(&self, map: &PixelMap) -> Vec<u64> {
        let s = self.size as i64;
        let mut hit = vec![false; self.ink.len()];
        for p in &self.points {
            let q = map.apply(p);
            let (x, y) = (q[0].floor() as i64, q[1].floor() as i64);
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (u, v) = (x + dx, y + dy);
                    if (0..s).contains(&u) && (0..s).contains(&v) {
                        hit[(v * s + u) as usize] = true;
                    }
                }
            }
        }
        let mut bits = vec![0u64; self.ink.len().div_ceil(64)];
        for (i, (&h, &on)) in hit.iter().zip(&self.ink).enumerate() {
            if h && on {
                bits[i / 64] |= 1 << (i % 64);
            }
        }
        bits
    }

    /// IoU of the attractor of `maps` (rasterised at the target's pixels) with the ink.
    fn attractor_iou(&self, maps: &[PixelMap], points: usize, seed: u64) -> f64 {
        let Some(pts) = attractor_points(maps, points, seed) else {
            return 0.0;
        };
        let s = self.size as i64;
        let mut on = vec![false; self.ink.len()];
        for q in pts {
            let (x, y) = (q[0].floor() as i64, q[1].floor() as i64);
            if (0..s).contains(&x) && (0..s).contains(&y) {
                on[(y * s + x) as usize] = true;
            }
        }
        let (mut both, mut either) = (0usize, 0usize);
        for (&a, &b) in on.iter().zip(&self.ink) {
            both += (a && b) as usize;
            either += (a || b) as usize;
        }
        both as f64 / either.max(1) as f64
    }
}

/// `n` points of the attractor of `maps` by one chaos game from `seed` (maps drawn ∝ |det|
/// with the evaluation renders' floor, 60 steps dropped); `None` when every map is
/// degenerate.
pub(crate) fn attractor_points(
    maps: &[PixelMap],
    n: usize,
    seed: u64,
) -> Option<Vec<Vector2<f64>>> {
    let affine: Vec<Affine2> = maps.iter().map(|m| Affine2 { m: m.g, b: m.h }).collect();
    let dets: Vec<f64> = affine.iter().map(|m| m.det().abs()).collect();
    let sampler = ProbabilityRule::default()
        .resolve(&dets)
        .and_then(|p| MapSampler::new(&p))
        .ok()?;
    let mut game = Trajectory::new(&affine, &sampler, seed, 0, 0.0);
    game.skip_steps(60);
    Some(
        (0..n)
            .map(|_| {
                let q = game.step();
                Vector2::new(q[0], q[1])
            })
            .collect(),
    )
}

/// `m` with its singular values clamped into `range` (the candidate searches of the plane and
/// of space).
pub(crate) fn clamp_singular_values<D>(
    m: &OMatrix<f64, D, D>,
    range: (f64, f64),
) -> OMatrix<f64, D, D>
where
    D: DimMin<D, Output = D> + DimSub<U1>,
    DefaultAllocator: Allocator<D, D> + Allocator<D> + Allocator<DimDiff<D, U1>>,
{
    let mut svd = m.clone().svd(true, true);
    for s in svd.singular_values.iter_mut() {
        *s = s.clamp(range.0, range.1);
    }
    svd.recompose().unwrap_or_else(|_| m.clone())
}

/// Adam's moments over a candidate map's few parameters (β₁ 0.9, β₂ 0.999, ε 10⁻⁸), for the
/// candidate searches of the plane and of space.
pub(crate) struct CandidateAdam<const N: usize> {
    m1: [f64; N],
    m2: [f64; N],
    t: i32,
}

impl<const N: usize> CandidateAdam<N> {
    pub(crate) fn new() -> Self {
        CandidateAdam {
            m1: [0.0; N],
            m2: [0.0; N],
            t: 0,
        }
    }

    /// The next step (to subtract) for `grad`, parameter `i` at the rate `rate(i)`.
    pub(crate) fn step(&mut self, grad: &[f64; N], rate: impl Fn(usize) -> f64) -> [f64; N] {
        let (b1, b2, eps) = (0.9f64, 0.999f64, 1e-8);
        self.t += 1;
        let mut delta = [0.0; N];
        for (i, d) in delta.iter_mut().enumerate() {
            self.m1[i] = b1 * self.m1[i] + (1.0 - b1) * grad[i];
            self.m2[i] = b2 * self.m2[i] + (1.0 - b2) * grad[i] * grad[i];
            let mh = self.m1[i] / (1.0 - b1.powi(self.t));
            let vh = self.m2[i] / (1.0 - b2.powi(self.t));
            *d = mh / (vh.sqrt() + eps) * rate(i);
        }
        delta
    }
}

/// One candidate: a random start moved by Adam on the containment objective. Returns the
/// map and the share of the ink's image within one pixel of the ink.
fn candidate(field: &Field, search: &CollageSearch, seed: u64, index: u64) -> (PixelMap, f64) {
    let mut rng = trajectory_rng(seed, index);
    let rot = |a: f64| Matrix2::new(a.cos(), -a.sin(), a.sin(), a.cos());
    let s1 = rng.random_range(0.25..0.8);
    let s2 = rng.random_range(0.1..0.6f64).min(s1);
    let (t, p) = (
        rng.random_range(0.0..std::f64::consts::TAU),
        rng.random_range(0.0..std::f64::consts::TAU),
    );
    let mut g = rot(t) * Matrix2::new(s1, 0.0, 0.0, s2) * rot(p);
    if rng.random::<bool>() {
        g *= Matrix2::new(1.0, 0.0, 0.0, -1.0);
    }
    let n = field.points.len();
    let centroid = field.points.iter().sum::<Vector2<f64>>() / n as f64;
    let anchor = field.points[rng.random_range(0..n)];
    let mut map = PixelMap {
        g,
        h: anchor - g * centroid,
    };
    let batch: Vec<Vector2<f64>> = (0..search.batch.min(n).max(1))
        .map(|_| field.points[rng.random_range(0..n)])
        .collect();
    let lambda = search.area_weight * field.size as f64 / 128.0;
    let (lr_g, lr_h) = (0.02, 0.01 * field.size as f64);
    let mut adam = CandidateAdam::<6>::new();
    for _ in 0..search.steps {
        let mut gg = Matrix2::zeros();
        let mut gh = Vector2::zeros();
        for x in &batch {
            let (d, grad) = field.sample(&map.apply(x));
            if d > 0.0 {
                gg += grad * x.transpose();
                gh += grad;
            }
        }
        let inv = batch.len() as f64;
        gg /= inv;
        gh /= inv;
        if let Some(ginv) = map.g.try_inverse() {
            gg -= lambda * ginv.transpose();
        }
        let grad = [gg[(0, 0)], gg[(0, 1)], gg[(1, 0)], gg[(1, 1)], gh[0], gh[1]];
        let delta = adam.step(&grad, |i| if i < 4 { lr_g } else { lr_h });
        let g = map.g - Matrix2::new(delta[0], delta[1], delta[2], delta[3]);
        map.g = clamp_singular_values(&g, search.scales);
        map.h -= Vector2::new(delta[4], delta[5]);
    }
    let inside = field
        .points
        .iter()
        .filter(|x| field.sample(&map.apply(x)).0 <= 1.0)
        .count();
    (map, inside as f64 / n as f64)
}

/// Moves the maps of a cover together towards an exact collage of the ink: rounds of a
/// symmetric closest-point fit (ICP). Each round pairs every mapped ink point off the ink with its
/// closest ink pixel (containment: the copies lie on the ink) and every ink pixel with the
/// closest point of any copy (coverage: the copies cover the ink), then gives each map the
/// affine map that fits its pairs best in least squares (each term a mean over its pairs,
/// plus a small pull to the map's current images so that a map with few pairs stays
/// put), its singular values clamped into the search's range; each map moves twice its
/// least-squares step.
fn refine_cover(field: &Field, maps: &mut [PixelMap], rounds: usize, scales: (f64, f64)) {
    let s = field.size;
    let stride = field.points.len().div_ceil(3000).max(1);
    let src: Vec<Vector2<f64>> = field.points.iter().step_by(stride).copied().collect();
    let ink_stride = field.points.len().div_ceil(6000).max(1);
    let ink: Vec<Vector2<f64>> = field.points.iter().step_by(ink_stride).copied().collect();
    let k = maps.len();
    let (wc, wv, damp) = (
        1.0 / (k * src.len()) as f64,
        1.0 / ink.len() as f64,
        0.05 / (k * src.len()) as f64,
    );
    let reach = (s / 8).max(4) as i64;
    for _ in 0..rounds {
        // Normal equations per map: Σ w·[x;1][x;1]ᵀ and Σ w·y·[x;1]ᵀ.
        let mut lhs = vec![nalgebra::Matrix3::<f64>::zeros(); k];
        let mut rhs = vec![nalgebra::Matrix2x3::<f64>::zeros(); k];
        let mut add = |i: usize, x: &Vector2<f64>, y: &Vector2<f64>, w: f64| {
            let xh = nalgebra::Vector3::new(x[0], x[1], 1.0);
            lhs[i] += w * xh * xh.transpose();
            rhs[i] += w * y * xh.transpose();
        };
        // Where each copy's points land, bucketed by pixel (CSR).
        let mut start = vec![0u32; s * s + 1];
        let mut placed: Vec<(usize, u32, u32, Vector2<f64>)> = Vec::with_capacity(k * src.len());
        for (i, m) in maps.iter().enumerate() {
            for (j, x) in src.iter().enumerate() {
                let q = m.apply(x);
                // Containment: towards the closest ink pixel, p − D(p)·∇D/|∇D|.
                let (d, g) = field.sample(&q);
                let n = g.norm();
                if d > 0.0 && n > 1e-9 {
                    add(i, x, &(q - g * (d / n)), wc);
                }
                add(i, x, &q, damp);
                let (u, v) = (q[0].floor(), q[1].floor());
                if u >= 0.0 && v >= 0.0 && (u as usize) < s && (v as usize) < s {
                    let cell = v as usize * s + u as usize;
                    start[cell + 1] += 1;
                    placed.push((cell, i as u32, j as u32, q));
                }
            }
        }
        for c in 0..s * s {
            start[c + 1] += start[c];
        }
        let mut fill = start.clone();
        // Each slot keeps the copied point with its map and source, so the search below
        // does not map the source again.
        let mut slots = vec![(0u32, 0u32, Vector2::zeros()); placed.len()];
        for &(cell, i, j, q) in &placed {
            slots[fill[cell] as usize] = (i, j, q);
            fill[cell] += 1;
        }
        // Coverage: each ink pixel pulls the closest copied point (searched ring by ring).
        for y in &ink {
            let (cx, cy) = (y[0].floor() as i64, y[1].floor() as i64);
            let mut best: Option<(f64, u32, u32)> = None;
            for r in 0..=reach {
                if let Some((d2, _, _)) = best
                    && (r as f64 - 1.0).max(0.0).powi(2) > d2
                {
                    break;
                }
                // The cells of the square ring at Chebyshev distance r.
                let edge = (cx - r)..=(cx + r);
                let sides = [cx - r, cx + r];
                for v in (cy - r)..=(cy + r) {
                    let full = (v - cy).abs() == r;
                    let us = edge.clone().filter(|u| full || sides.contains(u));
                    for u in
                        us.filter(|&u| (0..s as i64).contains(&u) && (0..s as i64).contains(&v))
                    {
                        let cell = v as usize * s + u as usize;
                        for &(i, j, q) in &slots[start[cell] as usize..start[cell + 1] as usize] {
                            let d2 = (q - y).norm_squared();
                            if best.is_none_or(|(b, _, _)| d2 < b) {
                                best = Some((d2, i, j));
                            }
                        }
                    }
                }
            }
            if let Some((_, i, j)) = best {
                add(i as usize, &src[j as usize], y, wv);
            }
        }
        for (i, m) in maps.iter_mut().enumerate() {
            let Some(inv) = lhs[i].try_inverse() else {
                continue;
            };
            let t = rhs[i] * inv;
            let g = Matrix2::new(t[(0, 0)], t[(0, 1)], t[(1, 0)], t[(1, 1)]);
            if !g.iter().all(|v| v.is_finite()) {
                continue;
            }
            // Over-relaxed (twice the least-squares step): the pairs already in place
            // anchor each map where it is, so a plain step covers half the way (measured on
            // the test below: 40 rounds plain reach what 20 over-relaxed do).
            let w = 2.0;
            let g = m.g + (g - m.g) * w;
            m.g = clamp_singular_values(&g, scales);
            m.h += (Vector2::new(t[(0, 2)], t[(1, 2)]) - m.h) * w;
        }
    }
}

/// Two maps that differ by less than a twentieth in the matrix and a pixel and a half in
/// the offset.
fn near(a: &PixelMap, b: &PixelMap) -> bool {
    (a.g - b.g).amax() < 0.05 && (a.h - b.h).amax() < 1.5
}

fn count(bits: &[u64]) -> u32 {
    bits.iter().map(|w| w.count_ones()).sum()
}

/// The scores by which starts are compared: for each start (maps in the inversion's
/// coordinates), the IoU of its attractor with the ink of `target`, as the search scores
/// its covers (one distance field for all).
pub fn start_scores(
    target: &[f32],
    size: usize,
    starts: &[&[Affine2]],
    seed: u64,
    search: &CollageSearch,
) -> Result<Vec<f64>> {
    let field = Field::new(target, size, search.ink_level)?;
    let stream = mix_seed(seed, 0xC011_A6E5);
    Ok(starts
        .iter()
        .map(|maps| {
            let pixel: Vec<PixelMap> = maps.iter().map(|m| to_pixel_frame(m, size)).collect();
            field.attractor_iou(&pixel, search.score_points, mix_seed(stream, 0))
        })
        .collect())
}

/// `k` maps whose attractor covers the bright part of `target` (`size × size`, row 0 at the
/// top), in the inversion's coordinates (`[−1, 1]²`, y up); see the module's description.
/// Deterministic for `seed`. The best of [`collage_covers`] (the first of equals).
pub fn collage_maps(
    target: &[f32],
    size: usize,
    k: usize,
    seed: u64,
    search: &CollageSearch,
) -> Result<Vec<Affine2>> {
    let covers = collage_covers(target, size, k, seed, search)?;
    let mut best = &covers[0];
    for c in &covers[1..] {
        if c.score > best.score {
            best = c;
        }
    }
    Ok(best.maps.clone())
}

/// One cover of the collage search, scored.
#[derive(Clone, Debug)]
pub struct ScoredCover {
    /// The IoU of its attractor with the ink (step 4 of the module's description).
    pub score: f64,
    /// Its maps, in the inversion's coordinates.
    pub maps: Vec<Affine2>,
    /// Which candidates it is made of (sorted) and whether it was refined: two covers of
    /// equal key are the same code.
    pub key: (Vec<usize>, bool),
}

/// Every cover the collage search scores, in the order it scores them (each greedy pass,
/// then its refined version where [`CollageSearch::refine`] asks for one); never empty.
pub fn collage_covers(
    target: &[f32],
    size: usize,
    k: usize,
    seed: u64,
    search: &CollageSearch,
) -> Result<Vec<ScoredCover>> {
    if k == 0 {
        return Err(Error::InvalidInput(
            "the collage start needs at least one map".into(),
        ));
    }
    let field = Field::new(target, size, search.ink_level)?;
    let stream = mix_seed(seed, 0xC011_A6E5);
    let mut found: Vec<(PixelMap, f64)> = (0..search.candidates as u64)
        .into_par_iter()
        .map(|i| candidate(&field, search, stream, i))
        .collect();
    // The candidates that hold; at least a few per map even on a picture that is no exact
    // collage of itself (the best by containment).
    let keep = found
        .iter()
        .filter(|(_, c)| *c >= search.containment)
        .count()
        .max((3 * k).min(found.len()));
    found.sort_by(|a, b| b.1.total_cmp(&a.1));
    found.truncate(keep);
    let maps: Vec<PixelMap> = found.iter().map(|(m, _)| *m).collect();
    let cover: Vec<Vec<u64>> = maps.par_iter().map(|m| field.coverage(m)).collect();

    let mut pick_rng = trajectory_rng(stream, u64::MAX);
    let choices = greedy_covers(&cover, k, search.covers, 0.05, &mut pick_rng, |i, j| {
        near(&maps[i], &maps[j])
    });
    let mut scored: Vec<ScoredCover> = Vec::new();
    for (trial, chosen) in choices.into_iter().enumerate() {
        let code: Vec<PixelMap> = chosen.iter().map(|&i| maps[i]).collect();
        let mut key = chosen.clone();
        key.sort_unstable();
        let mut versions = vec![(code, false)];
        if search.refine > 0 {
            let mut refined = versions[0].0.clone();
            refine_cover(&field, &mut refined, search.refine, search.scales);
            versions.push((refined, true));
        }
        for (code, refined) in versions {
            let iou =
                field.attractor_iou(&code, search.score_points, mix_seed(stream, trial as u64));
            scored.push(ScoredCover {
                score: iou,
                maps: code.iter().map(|m| to_inversion_frame(m, size)).collect(),
                key: (key.clone(), refined),
            });
        }
    }
    Ok(scored)
}

/// Step 2 of the search, for a plane or for space: `trials` (at least one) choices of `k`
/// candidates whose coverage bit sets `cover` together cover the most. Each pick takes the
/// candidate of the largest gain — the cells it adds, plus `size_weight` times all it
/// covers (the plane's search: a twentieth) —
/// that is neither chosen nor `near` a chosen one; the first trial is deterministic, the
/// others weigh each candidate's gain by a factor in [0.7, 1) drawn from `rng` (one per
/// candidate and trial). Fewer distinct candidates than maps repeat the largest ones.
pub(crate) fn greedy_covers<R: Rng>(
    cover: &[Vec<u64>],
    k: usize,
    trials: usize,
    size_weight: f64,
    rng: &mut R,
    near: impl Fn(usize, usize) -> bool,
) -> Vec<Vec<usize>> {
    let totals: Vec<f64> = cover.iter().map(|c| count(c) as f64).collect();
    (0..trials.max(1))
        .map(|trial| {
            let jitter: Vec<f64> = (0..cover.len())
                .map(|_| {
                    if trial == 0 {
                        1.0
                    } else {
                        rng.random_range(0.7..1.0)
                    }
                })
                .collect();
            let mut covered = vec![0u64; cover.first().map_or(0, Vec::len)];
            let mut chosen: Vec<usize> = Vec::with_capacity(k);
            while chosen.len() < k {
                let mut pick: Option<(f64, usize)> = None;
                for (i, c) in cover.iter().enumerate() {
                    if chosen.iter().any(|&j| j == i || near(j, i)) {
                        continue;
                    }
                    let fresh: u32 = c
                        .iter()
                        .zip(&covered)
                        .map(|(a, b)| (a & !b).count_ones())
                        .sum();
                    let gain = (fresh as f64 + size_weight * totals[i]) * jitter[i];
                    if pick.is_none_or(|(g, _)| gain > g) {
                        pick = Some((gain, i));
                    }
                }
                let i = pick.map_or(chosen.len() % cover.len(), |(_, i)| i);
                for (w, c) in covered.iter_mut().zip(&cover[i]) {
                    *w |= c;
                }
                chosen.push(i);
            }
            chosen
        })
        .collect()
}

/// A pixel-coordinate map in the inversion's coordinates: `x = 2u/S − 1`, `y = 1 − 2v/S`,
/// i.e. `x = A·p + c` with `A = diag(2/S, −2/S)`, `c = (−1, 1)`, so `M = A·G·A⁻¹` and
/// `b = A·h + c − M·c`.
pub(crate) fn to_inversion_frame(map: &PixelMap, size: usize) -> Affine2 {
    let a = 2.0 / size as f64;
    let scale = Matrix2::new(a, 0.0, 0.0, -a);
    let unscale = Matrix2::new(1.0 / a, 0.0, 0.0, -1.0 / a);
    let c = Vector2::new(-1.0, 1.0);
    let m = scale * map.g * unscale;
    let b = scale * map.h + c - m * c;
    Affine2 { m, b }
}

/// The inverse of [`to_inversion_frame`]: `G = A⁻¹·M·A`, `h = A⁻¹·(M·c + b − c)`.
fn to_pixel_frame(map: &Affine2, size: usize) -> PixelMap {
    let a = 2.0 / size as f64;
    let scale = Matrix2::new(a, 0.0, 0.0, -a);
    let unscale = Matrix2::new(1.0 / a, 0.0, 0.0, -1.0 / a);
    let c = Vector2::new(-1.0, 1.0);
    PixelMap {
        g: unscale * map.m * scale,
        h: unscale * (map.m * c + map.b - c),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ifslab::model::Map;

    /// The frame conversion agrees with mapping pixel centres through both coordinates.
    #[test]
    fn pixel_maps_convert_to_the_inversion_frame() {
        let size = 64;
        let map = PixelMap {
            g: Matrix2::new(0.3, -0.2, 0.1, 0.5),
            h: Vector2::new(7.0, -3.0),
        };
        let affine = to_inversion_frame(&map, size);
        let back = to_pixel_frame(&affine, size);
        assert!((back.g - map.g).amax() < 1e-12 && (back.h - map.h).amax() < 1e-9);
        let to_xy = |p: Vector2<f64>| {
            [
                2.0 * p[0] / size as f64 - 1.0,
                1.0 - 2.0 * p[1] / size as f64,
            ]
        };
        for p in [Vector2::new(3.5, 10.5), Vector2::new(40.0, 60.0)] {
            let lhs = affine.apply(to_xy(p));
            let rhs = to_xy(map.apply(&p));
            assert!((lhs[0] - rhs[0]).abs() < 1e-12 && (lhs[1] - rhs[1]).abs() < 1e-12);
        }
    }
    /// The closest-point refinement pulls a perturbed Sierpiński code back to the exact
    /// collage: its attractor matches the ink again and each map returns near its truth.
    #[test]
    fn refinement_restores_a_perturbed_collage() {
        let size = 96;
        let corners = [
            Vector2::new(8.0, 88.0),
            Vector2::new(88.0, 88.0),
            Vector2::new(48.0, 8.0),
        ];
        let truth: Vec<PixelMap> = corners
            .iter()
            .map(|v| PixelMap {
                g: Matrix2::identity() * 0.5,
                h: v * 0.5,
            })
            .collect();
        let mut image = vec![0.0f32; size * size];
        let mut p = Vector2::new(48.0, 48.0);
        let mut rng = trajectory_rng(5, 0);
        for step in 0..200_000 {
            p = truth[rng.random_range(0..3)].apply(&p);
            if step > 20 {
                image[p[1] as usize * size + p[0] as usize] = 1.0;
            }
        }
        let field = Field::new(&image, size, 0.2).unwrap();
        let nudges = [
            (
                Matrix2::new(0.06, -0.05, 0.04, -0.06),
                Vector2::new(3.0, -2.5),
            ),
            (
                Matrix2::new(-0.05, 0.06, 0.05, 0.04),
                Vector2::new(-2.5, 3.0),
            ),
            (
                Matrix2::new(0.05, 0.04, -0.06, 0.05),
                Vector2::new(2.0, 3.0),
            ),
        ];
        let mut maps: Vec<PixelMap> = truth
            .iter()
            .zip(&nudges)
            .map(|(m, (dg, dh))| PixelMap {
                g: m.g + dg,
                h: m.h + dh,
            })
            .collect();
        let before = field.attractor_iou(&maps, 60_000, 1);
        refine_cover(&field, &mut maps, 20, (0.02, 0.9));
        let after = field.attractor_iou(&maps, 60_000, 1);
        assert!(
            after >= 0.8 && after > before + 0.2,
            "IoU {before:.3} -> {after:.3}"
        );
        for (m, t) in maps.iter().zip(&truth) {
            assert!(
                (m.g - t.g).amax() < 0.03 && (m.h - t.h).amax() < 2.0,
                "{m:?} against {t:?}"
            );
        }
    }

    /// A picture with no ink, or too little, is refused with a reason.
    #[test]
    fn a_picture_without_ink_is_refused() {
        let err = collage_maps(&vec![0.0; 64 * 64], 64, 3, 0, &CollageSearch::default());
        assert!(err.unwrap_err().to_string().contains("no bright pixels"));
        let mut dot = vec![0.0; 64 * 64];
        dot[100] = 1.0;
        let err = collage_maps(&dot, 64, 3, 0, &CollageSearch::default());
        assert!(err.unwrap_err().to_string().contains("1 ink pixel"));
    }
}
