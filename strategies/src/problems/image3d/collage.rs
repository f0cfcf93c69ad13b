//! The collage start in space: an IFS of affine maps of R³ assembled from copies of the
//! visual hull found inside the hull itself — the 2-D collage start
//! ([`crate::problems::image::collage`]) on the carved voxels instead of a picture's ink.
//!
//! The hull's EM code tiles the hull with similitudes of about equal size: a fern, one frond
//! map of 0.86 beside two leaflets of 0.3 and a stem, is fitted as four pieces of 0.42–0.60,
//! a basin the image loss does not leave (README, "The fern, diagnosed"). The largest map
//! whose image of the hull stays inside it is the frond; what it leaves uncovered, the
//! leaflets. So:
//!
//! 1. **Candidate maps.** From random affine starts (two random rotations about three
//!    singular values, mirrored half the time), each map `g` is moved by Adam to minimise
//!    `mean_x D(g(x)) − λ·log|det g|` over points `x` of the hull, `D` the distance (in
//!    voxels) to the nearest hull voxel: the copy must lie in the hull, as large as it can.
//!    Singular values stay in [`CollageSearch3::scales`]. A candidate is kept when a share
//!    [`CollageSearch3::containment`] of its copy lies within one voxel of the hull.
//! 2. **Covers.** `k` candidates that together cover the most hull voxels, chosen greedily
//!    (the 2-D search's rule: a deterministic pass, then randomised ones).
//! 3. **Selection.** Each cover is drawn (chaos game, maps ∝ |det| floored at 1 %, the fit's
//!    rule) and projected through every camera; its score is the mean over views of the
//!    IoU of the pixels its points fall in with the view's ink. The hull's EM code competes
//!    on the same score (`Start3d::Collage`).
//!
//! Every candidate draws from its own seeded stream and the reductions run in index order,
//! so the result depends on the seed only, not on the thread count.
//!
//! ## References
//! - M. F. Barnsley, V. Ervin, D. Hardin and J. Lancaster, *Solution of an inverse problem
//!   for fractals and other sets*, PNAS 83(7), 1986 (the collage theorem).

use ifslab::chaos::{ChaosGame, mix_seed, points3, trajectory_rng};
use ifslab::image::distance_to_3d;
use ifslab::model::ProbabilityRule;
use ifslab::model::map3::Affine3;
use nalgebra::{Matrix3, Vector3};
use rand::Rng;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::problems::image::collage::{CandidateAdam, clamp_singular_values, greedy_covers};
use crate::problems::image3d::hull::Hull;
use crate::problems::image3d::views::Views;

/// Settings of the search in space.
#[derive(Clone, Debug, PartialEq)]
pub struct CollageSearch3 {
    /// Random starts of the candidate search.
    pub candidates: usize,
    /// Adam steps per candidate.
    pub steps: usize,
    /// Hull points per candidate's objective.
    pub batch: usize,
    /// λ, the reward for a map's volume, in voxels of distance per unit of `log|det|` at a
    /// 64-voxel hull (scaled with its resolution).
    pub area_weight: f64,
    /// Share of a candidate's copy that must lie within one voxel of the hull.
    pub containment: f64,
    /// Greedy covers scored (the first deterministic).
    pub covers: usize,
    /// Range of a map's singular values.
    pub scales: (f64, f64),
    /// Chaos-game points of the attractor that scores a cover.
    pub score_points: usize,
    /// A view's pixel is ink from this level on (the hull's threshold).
    pub ink_level: f64,
    /// Weight of all the voxels a candidate covers in its greedy gain, beside the voxels it
    /// adds (negative: overlap with the maps already chosen is charged).
    pub size_weight: f64,
}

impl Default for CollageSearch3 {
    fn default() -> Self {
        CollageSearch3 {
            candidates: 4000,
            steps: 150,
            batch: 400,
            area_weight: 0.1,
            containment: 0.9,
            covers: 10,
            scales: (0.02, 0.9),
            score_points: 40_000,
            ink_level: 0.3,
            size_weight: 0.05,
        }
    }
}

/// A map in voxel coordinates (voxel `(i, j, k)` spans `[i, i + 1] × …`).
#[derive(Clone, Copy, Debug, PartialEq)]
struct VoxelMap {
    g: Matrix3<f64>,
    h: Vector3<f64>,
}

impl VoxelMap {
    fn apply(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.g * p + self.h
    }
}

/// The hull as the search sees it: which voxels it keeps (and their rank among the kept
/// ones), the distance to it and its gradient, and the kept voxels' centres.
struct Field3 {
    r: usize,
    /// Half the cube's side, and a voxel's side (world units).
    extent: f64,
    voxel: f64,
    /// For every voxel of the cube, its index among the kept ones (`u32::MAX`: carved).
    rank: Vec<u32>,
    dist: Vec<f32>,
    grad: Vec<[f32; 3]>,
    points: Vec<Vector3<f64>>,
    /// See [`Field3::sources`].
    sources: Vec<Vector3<f64>>,
}

/// Most hull voxels whose copies are measured (see [`Field3::sources`]).
const SOURCES: usize = 8000;

impl Field3 {
    fn new(hull: &Hull) -> Result<Field3> {
        let r = hull.resolution;
        if hull.kept.len() < 8 {
            return Err(Error::InvalidInput(format!(
                "the visual hull has {} voxel(s); the collage start needs at least 8",
                hull.kept.len()
            )));
        }
        let mut mask = vec![false; r * r * r];
        let mut rank = vec![u32::MAX; r * r * r];
        for (n, &i) in hull.kept.iter().enumerate() {
            mask[i] = true;
            rank[i] = n as u32;
        }
        let dist: Vec<f32> = distance_to_3d(&mask, [r, r, r])
            .expect("the hull has voxels")
            .into_iter()
            .map(|d| d as f32)
            .collect();
        let idx = |x: usize, y: usize, z: usize| x + r * (y + r * z);
        let mut grad = vec![[0.0f32; 3]; r * r * r];
        for z in 0..r {
            for y in 0..r {
                for x in 0..r {
                    let d = |lo: usize, hi: usize, a: usize, b: usize| {
                        (dist[hi] - dist[lo]) / (b - a).max(1) as f32
                    };
                    let (x0, x1) = (x.saturating_sub(1), (x + 1).min(r - 1));
                    let (y0, y1) = (y.saturating_sub(1), (y + 1).min(r - 1));
                    let (z0, z1) = (z.saturating_sub(1), (z + 1).min(r - 1));
                    grad[idx(x, y, z)] = [
                        d(idx(x0, y, z), idx(x1, y, z), x0, x1),
                        d(idx(x, y0, z), idx(x, y1, z), y0, y1),
                        d(idx(x, y, z0), idx(x, y, z1), z0, z1),
                    ];
                }
            }
        }
        let points: Vec<Vector3<f64>> = hull
            .kept
            .iter()
            .map(|&i| {
                let (x, y, z) = (i % r, (i / r) % r, i / (r * r));
                Vector3::new(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5)
            })
            .collect();
        let stride = points.len().div_ceil(SOURCES).max(1);
        let sources = points.iter().step_by(stride).copied().collect();
        Ok(Field3 {
            r,
            extent: hull.extent,
            voxel: hull.voxel(),
            rank,
            dist,
            grad,
            points,
            sources,
        })
    }

    /// Distance to the hull at `p` (trilinear between voxel centres; outside the cube, plus
    /// the distance to it) and its gradient.
    fn sample(&self, p: &Vector3<f64>) -> (f64, Vector3<f64>) {
        let r = self.r;
        let hi = r as f64 - 1.0;
        let mut base = [0usize; 3];
        let mut frac = [0.0f64; 3];
        let mut d = 0.0;
        let mut g = Vector3::zeros();
        for a in 0..3 {
            let q = p[a] - 0.5;
            let c = q.clamp(0.0, hi);
            let o = q - c;
            d += o.abs();
            g[a] += o.signum() * f64::from(u8::from(o != 0.0));
            base[a] = (c.floor() as usize).min(r.saturating_sub(2));
            frac[a] = c - base[a] as f64;
        }
        for corner in 0..8 {
            let mut w = 1.0;
            let mut at = [0usize; 3];
            for a in 0..3 {
                let up = (corner >> a) & 1 == 1;
                at[a] = (base[a] + usize::from(up)).min(r - 1);
                w *= if up { frac[a] } else { 1.0 - frac[a] };
            }
            let i = at[0] + r * (at[1] + r * at[2]);
            d += w * f64::from(self.dist[i]);
            for a in 0..3 {
                g[a] += w * f64::from(self.grad[i][a]);
            }
        }
        (d, g)
    }

    /// The hull voxels whose copies are measured: at most [`SOURCES`] of them, every
    /// `⌈K / SOURCES⌉`-th (a copy's containment and its cover, dilated by a voxel, are read
    /// on them).
    fn sources(&self) -> &[Vector3<f64>] {
        &self.sources
    }

    /// The hull voxels within one voxel of `map`'s copy of the hull, as a bit set over the
    /// kept voxels.
    fn coverage(&self, map: &VoxelMap) -> Vec<u64> {
        let r = self.r as i64;
        let mut bits = vec![0u64; self.points.len().div_ceil(64)];
        for p in &self.sources {
            let q = map.apply(p);
            let c = [
                q[0].floor() as i64,
                q[1].floor() as i64,
                q[2].floor() as i64,
            ];
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let (x, y, z) = (c[0] + dx, c[1] + dy, c[2] + dz);
                        if [x, y, z].iter().all(|v| (0..r).contains(v)) {
                            let n = self.rank[(x + r * (y + r * z)) as usize];
                            if n != u32::MAX {
                                bits[n as usize / 64] |= 1 << (n % 64);
                            }
                        }
                    }
                }
            }
        }
        bits
    }

    /// A voxel-coordinate map in world coordinates: `x_w = a·p − e` (a voxel's side `a`, the
    /// cube's half side `e`), so `M = G` and `b = G·e + a·H − e`.
    fn to_world(&self, map: &VoxelMap) -> Affine3 {
        let e = Vector3::repeat(self.extent);
        Affine3 {
            m: map.g,
            b: map.g * e + map.h * self.voxel - e,
        }
    }
}

/// A rotation of space uniform on SO(3) (the library's Haar draw).
fn random_rotation<R: Rng>(rng: &mut R) -> Matrix3<f64> {
    let q = ifslab::model::similitude::random_rotation(3, rng);
    Matrix3::from_fn(|r, c| q[(r, c)])
}

/// One candidate: a random start moved by Adam on the containment objective; the map and
/// the share of the hull's copy within one voxel of the hull.
fn candidate(field: &Field3, search: &CollageSearch3, seed: u64, index: u64) -> (VoxelMap, f64) {
    let mut rng = trajectory_rng(seed, index);
    // R₁·diag(s)·R₂, both rotations uniform on SO(3), mirrored half the time.
    let s1 = rng.random_range(0.25..0.8);
    let s2 = rng.random_range(0.1..0.6f64).min(s1);
    let s3 = rng.random_range(0.1..0.6f64).min(s2);
    let mut g = random_rotation(&mut rng)
        * Matrix3::from_diagonal(&Vector3::new(s1, s2, s3))
        * random_rotation(&mut rng);
    if rng.random::<bool>() {
        g *= Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
    }
    let n = field.points.len();
    let centroid = field.points.iter().sum::<Vector3<f64>>() / n as f64;
    let anchor = field.points[rng.random_range(0..n)];
    let mut map = VoxelMap {
        g,
        h: anchor - g * centroid,
    };
    let batch: Vec<Vector3<f64>> = (0..search.batch.min(n).max(1))
        .map(|_| field.points[rng.random_range(0..n)])
        .collect();
    let lambda = search.area_weight * field.r as f64 / 64.0;
    let (lr_g, lr_h) = (0.02, 0.01 * field.r as f64);
    let mut adam = CandidateAdam::<12>::new();
    for _ in 0..search.steps {
        let mut gg = Matrix3::zeros();
        let mut gh = Vector3::zeros();
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
        let grad: [f64; 12] =
            std::array::from_fn(|i| if i < 9 { gg[(i / 3, i % 3)] } else { gh[i - 9] });
        let delta = adam.step(&grad, |i| if i < 9 { lr_g } else { lr_h });
        let g = map.g - Matrix3::from_row_slice(&delta[..9]);
        map.g = clamp_singular_values(&g, search.scales);
        map.h -= Vector3::new(delta[9], delta[10], delta[11]);
    }
    let sources = field.sources();
    let inside = sources
        .iter()
        .filter(|x| field.sample(&map.apply(x)).0 <= 1.0)
        .count();
    (map, inside as f64 / sources.len() as f64)
}

/// Every candidate of step 1, the most contained first (ties in index order).
fn candidates(field: &Field3, search: &CollageSearch3, stream: u64) -> Vec<(VoxelMap, f64)> {
    let mut found: Vec<(VoxelMap, f64)> = (0..search.candidates as u64)
        .into_par_iter()
        .map(|i| candidate(field, search, stream, i))
        .collect();
    found.sort_by(|a, b| b.1.total_cmp(&a.1));
    found
}

/// The candidate maps of step 1 in world coordinates, each with the share of its copy of
/// the hull within one voxel of the hull, the most contained first: what the covers are
/// assembled from.
pub fn collage_candidates3(
    hull: &Hull,
    seed: u64,
    search: &CollageSearch3,
) -> Result<Vec<(Affine3, f64)>> {
    let field = Field3::new(hull)?;
    let found = candidates(&field, search, mix_seed(seed, 0xC011_A6E3));
    Ok(found.iter().map(|(m, c)| (field.to_world(m), *c)).collect())
}

/// Two maps that differ by less than a twentieth in the matrix and a voxel and a half in
/// the offset.
fn near(a: &VoxelMap, b: &VoxelMap) -> bool {
    (a.g - b.g).amax() < 0.05 && (a.h - b.h).amax() < 1.5
}

/// The mean over `views` of the IoU of the pixels the attractor of `maps` (world
/// coordinates; drawn ∝ |det| floored at 1 %, `points` of them from `seed`) falls in with
/// the view's ink (pixels at `ink_level` or more); 0 for a code whose every map is
/// degenerate.
pub fn silhouette_score(
    views: &Views,
    maps: &[Affine3],
    points: usize,
    ink_level: f64,
    seed: u64,
) -> Result<f64> {
    let dets: Vec<f64> = maps.iter().map(Affine3::abs_det).collect();
    let Ok(probs) = ProbabilityRule::default().resolve(&dets) else {
        return Ok(0.0);
    };
    let game = ChaosGame {
        trajectories: 200,
        length: points.div_ceil(200) + 20,
        warmup: 20,
        start_half_width: 1.0,
        seed,
    };
    let pts = points3(&game, maps, Some(&probs))?;
    let (w, h) = views.size();
    let level = ink_level as f32;
    let total: f64 = (0..views.len())
        .into_par_iter()
        .map(|v| {
            let cam = &views.cameras[v];
            let mut on = vec![false; w * h];
            for p in &pts {
                if let Some([u, y]) = cam.project(*p)
                    && u >= 0.0
                    && y >= 0.0
                    && (u as usize) < w
                    && (y as usize) < h
                {
                    on[y as usize * w + u as usize] = true;
                }
            }
            let (mut both, mut either) = (0usize, 0usize);
            for (&a, &b) in on.iter().zip(views.plane(v)) {
                let ink = b >= level;
                both += usize::from(a && ink);
                either += usize::from(a || ink);
            }
            both as f64 / either.max(1) as f64
        })
        .collect::<Vec<f64>>()
        .iter()
        .sum();
    Ok(total / views.len() as f64)
}

/// One cover of the search in space, scored.
#[derive(Clone, Debug)]
pub struct ScoredCover3 {
    /// Its silhouettes' mean IoU with the views' ink ([`silhouette_score`]).
    pub score: f64,
    /// Its maps, in world coordinates.
    pub maps: Vec<Affine3>,
}

/// Every cover the search scores for `k` maps on `hull` (the best first; ties keep the
/// order they were scored in); see the module's description. Deterministic for `seed`.
pub fn collage_covers3(
    hull: &Hull,
    views: &Views,
    k: usize,
    seed: u64,
    search: &CollageSearch3,
) -> Result<Vec<ScoredCover3>> {
    if k == 0 {
        return Err(Error::InvalidInput(
            "the collage start needs at least one map".into(),
        ));
    }
    let field = Field3::new(hull)?;
    let stream = mix_seed(seed, 0xC011_A6E3);
    let mut found = candidates(&field, search, stream);
    let keep = found
        .iter()
        .filter(|(_, c)| *c >= search.containment)
        .count()
        .max((3 * k).min(found.len()));
    found.truncate(keep);
    let maps: Vec<VoxelMap> = found.iter().map(|(m, _)| *m).collect();
    let cover: Vec<Vec<u64>> = maps.par_iter().map(|m| field.coverage(m)).collect();
    let mut pick_rng = trajectory_rng(stream, u64::MAX);
    let choices = greedy_covers(
        &cover,
        k,
        search.covers,
        search.size_weight,
        &mut pick_rng,
        |i, j| near(&maps[i], &maps[j]),
    );
    let mut scored = choices
        .iter()
        .enumerate()
        .map(|(trial, chosen)| {
            let world: Vec<Affine3> = chosen.iter().map(|&i| field.to_world(&maps[i])).collect();
            let score = silhouette_score(
                views,
                &world,
                search.score_points,
                search.ink_level,
                mix_seed(stream, trial as u64),
            )?;
            Ok(ScoredCover3 { score, maps: world })
        })
        .collect::<Result<Vec<_>>>()?;
    scored.sort_by(|a, b| b.score.total_cmp(&a.score));
    Ok(scored)
}
