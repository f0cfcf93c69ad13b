//! The parallel chaos game: b trajectories of length l, warm-up m dropped.

use rand::{Rng, RngCore};
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::chaos::rng::trajectory_rng;
use crate::chaos::sampler::MapSampler;
use crate::error::{Error, Result};
use crate::isa::Isa;
use crate::model::{AffineN, Map2};

/// A point farther than this from the origin has left every attractor an affine IFS can
/// have: its trajectory is reported as divergent.
pub const DIVERGENCE_BOUND: f64 = 1e100;

/// Whether a point is still finite and within [`DIVERGENCE_BOUND`].
#[inline(always)]
pub fn is_bounded(p: &[f64]) -> bool {
    p.iter().all(|v| v.abs() <= DIVERGENCE_BOUND)
}

/// Layout and seed of a chaos-game run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ChaosGame {
    /// Number of independent trajectories b.
    pub trajectories: usize,
    /// Steps per trajectory l, warm-up included.
    pub length: usize,
    /// Leading steps m of each trajectory that are dropped.
    pub warmup: usize,
    /// Start points are uniform in `[−h, h]^H`.
    pub start_half_width: f64,
    /// Seed of the whole run.
    pub seed: u64,
}

impl Default for ChaosGame {
    /// The chaotic-splatting paper's layout: 2000 × 250, first 10 dropped, starts in [−5, 5]².
    fn default() -> Self {
        ChaosGame {
            trajectories: 2000,
            length: 250,
            warmup: 10,
            start_half_width: 5.0,
            seed: 0,
        }
    }
}

impl ChaosGame {
    /// Checks the layout; an error names the field to change.
    pub fn validate(&self) -> Result<()> {
        if self.trajectories == 0 {
            return Err(Error::param("trajectories", "must be at least 1"));
        }
        if self.length <= self.warmup {
            return Err(Error::param(
                "length",
                format!(
                    "must exceed warmup ({}) so each trajectory keeps a point, got {}",
                    self.warmup, self.length
                ),
            ));
        }
        if !(self.start_half_width.is_finite() && self.start_half_width >= 0.0) {
            return Err(Error::param(
                "start_half_width",
                format!("must be finite and ≥ 0, got {}", self.start_half_width),
            ));
        }
        Ok(())
    }

    /// Points kept per trajectory (l − m).
    pub fn kept_per_trajectory(&self) -> usize {
        self.length - self.warmup
    }

    /// Total points kept, b·(l − m).
    pub fn total_points(&self) -> usize {
        self.trajectories * self.kept_per_trajectory()
    }

    /// A 2-D trajectory, positioned at its start point (nothing dropped yet).
    pub fn trajectory<'a, M: Map2>(
        &self,
        maps: &'a [M],
        sampler: &'a MapSampler,
        index: u64,
    ) -> Trajectory<'a, M> {
        Trajectory::new(maps, sampler, self.seed, index, self.start_half_width)
    }

    /// Runs the game and keeps every point after warm-up, trajectory-major
    /// (`points[i·(l−m) + k]` is step `m + k` of trajectory `i`), on the instruction set
    /// this CPU has best.
    pub fn generate<M: Map2>(&self, maps: &[M], probs: &[f64]) -> Result<Points> {
        self.generate_with_isa(maps, probs, Isa::detect())
    }

    /// [`ChaosGame::generate`] with the trajectories on instruction set `isa` (an error if
    /// this CPU lacks it): the same points on every instruction set.
    pub fn generate_with_isa<M: Map2>(
        &self,
        maps: &[M],
        probs: &[f64],
        isa: Isa,
    ) -> Result<Points> {
        let isa = isa.checked()?;
        self.validate()?;
        if maps.is_empty() {
            return Err(Error::Empty("the code has no maps".into()));
        }
        let sampler = MapSampler::new(probs)?;
        if sampler.len() != maps.len() {
            return Err(Error::Shape(format!(
                "{} probabilities for {} maps",
                sampler.len(),
                maps.len()
            )));
        }
        let kept = self.kept_per_trajectory();
        let mut data = vec![[0.0; 2]; self.total_points()];
        data.par_chunks_mut(kept)
            .enumerate()
            .try_for_each(|(i, out)| {
                let t = self.trajectory(maps, &sampler, i as u64);
                match isa {
                    #[cfg(target_arch = "x86_64")]
                    // SAFETY: `isa` is `Fma` only after `Isa::checked` found AVX2, FMA and
                    // BMI1/2 on this CPU.
                    Isa::Fma => unsafe { fill_fma(t, self.warmup, out) },
                    _ => fill(t, self.warmup, out),
                }
                if !is_bounded(&out[kept - 1]) {
                    // Escaping is absorbing for the expanding codes that diverge: find where it started.
                    let k = out.iter().position(|p| !is_bounded(p)).unwrap_or(kept - 1);
                    return Err(Error::Divergent {
                        trajectory: i,
                        step: self.warmup + k,
                    });
                }
                Ok(())
            })?;
        Ok(Points {
            data,
            trajectories: self.trajectories,
            per_trajectory: kept,
        })
    }
}

/// `warmup` steps of `t` dropped, then one point per entry of `out`.
#[inline(always)]
fn fill<M: Map2>(mut t: Trajectory<'_, M>, warmup: usize, out: &mut [[f64; 2]]) {
    for _ in 0..warmup {
        t.step();
    }
    for o in out.iter_mut() {
        *o = t.step();
    }
}

/// [`fill`] compiled with AVX2, FMA and BMI1/2 ([`crate::isa`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2")]
fn fill_fma<M: Map2>(t: Trajectory<'_, M>, warmup: usize, out: &mut [[f64; 2]]) {
    fill(t, warmup, out)
}

/// Points of a chaos-game run, trajectory-major.
#[derive(Clone, Debug)]
pub struct Points {
    /// The points.
    pub data: Vec<[f64; 2]>,
    /// Number of trajectories.
    pub trajectories: usize,
    /// Points per trajectory.
    pub per_trajectory: usize,
}

impl Points {
    /// Axis-aligned bounding box `(min, max)`.
    pub fn bbox(&self) -> ([f64; 2], [f64; 2]) {
        bbox(&self.data)
    }
}

/// Axis-aligned bounding box of a point set; `([+∞; 2], [−∞; 2])` when empty.
pub fn bbox(points: &[[f64; 2]]) -> ([f64; 2], [f64; 2]) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in points {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

/// One 2-D chaos-game trajectory: its own generator, its current point.
pub struct Trajectory<'a, M> {
    maps: &'a [M],
    sampler: &'a MapSampler,
    rng: Xoshiro256PlusPlus,
    p: [f64; 2],
}

impl<'a, M: Map2> Trajectory<'a, M> {
    /// Trajectory `index` of a run seeded with `seed`, starting uniformly in `[−h, h]²`.
    pub fn new(
        maps: &'a [M],
        sampler: &'a MapSampler,
        seed: u64,
        index: u64,
        half_width: f64,
    ) -> Self {
        let mut rng = trajectory_rng(seed, index);
        let p = if half_width > 0.0 {
            [
                rng.random_range(-half_width..half_width),
                rng.random_range(-half_width..half_width),
            ]
        } else {
            [0.0, 0.0]
        };
        Trajectory {
            maps,
            sampler,
            rng,
            p,
        }
    }

    /// The current point.
    pub fn point(&self) -> [f64; 2] {
        self.p
    }

    /// One step: draw a map, move the point, return the map index and the new point.
    #[inline(always)]
    pub fn step_indexed(&mut self) -> (usize, [f64; 2]) {
        let k = self.sampler.pick(self.rng.next_u64());
        // `pick` returns < sampler.len(), which callers match to maps.len().
        let map = &self.maps[k];
        self.p = map.apply(self.p);
        (k, self.p)
    }

    /// One step, returning the new point.
    #[inline(always)]
    pub fn step(&mut self) -> [f64; 2] {
        self.step_indexed().1
    }

    /// Advances `n` steps without returning the points (warm-up).
    pub fn skip_steps(&mut self, n: usize) {
        for _ in 0..n {
            self.step();
        }
    }
}

/// The chaos game for maps in any dimension H: returns `b·(l − m)` points as a flat
/// row-major array (H numbers per point), trajectory-major.
pub fn generate_nd(game: &ChaosGame, maps: &[AffineN], probs: &[f64]) -> Result<Vec<f64>> {
    game.validate()?;
    let h = maps
        .first()
        .ok_or_else(|| Error::Empty("the code has no maps".into()))?
        .dim();
    if maps.iter().any(|m| m.dim() != h) {
        return Err(Error::Shape("maps of different dimensions".into()));
    }
    let sampler = MapSampler::new(probs)?;
    if sampler.len() != maps.len() {
        return Err(Error::Shape(format!(
            "{} probabilities for {} maps",
            sampler.len(),
            maps.len()
        )));
    }
    let kept = game.kept_per_trajectory();
    let mut data = vec![0.0; game.total_points() * h];
    data.par_chunks_mut(kept * h)
        .enumerate()
        .try_for_each(|(i, out)| {
            let mut rng = trajectory_rng(game.seed, i as u64);
            let hw = game.start_half_width;
            let mut p: Vec<f64> = (0..h)
                .map(|_| {
                    if hw > 0.0 {
                        rng.random_range(-hw..hw)
                    } else {
                        0.0
                    }
                })
                .collect();
            let mut q = vec![0.0; h];
            for step in 0..game.length {
                let k = sampler.pick(rng.next_u64());
                maps[k].apply_into(&p, &mut q);
                std::mem::swap(&mut p, &mut q);
                if step >= game.warmup {
                    let j = step - game.warmup;
                    out[j * h..(j + 1) * h].copy_from_slice(&p);
                }
            }
            if !is_bounded(&p) {
                let first_bad = out
                    .chunks_exact(h)
                    .position(|pt| !is_bounded(pt))
                    .unwrap_or(kept - 1);
                return Err(Error::Divergent {
                    trajectory: i,
                    step: game.warmup + first_bad,
                });
            }
            Ok(())
        })?;
    Ok(data)
}
