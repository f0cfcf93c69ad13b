//! The 3-D chaos game with a tape, and the backward scan through it: the 3-D form of the
//! splat's `trajectories.rs`, what the multi-view splat ([`crate::render::splat3d`]) runs.
//!
//! Trajectory `j` draws its start point (uniform in `[−h, h]³`) and its map sequence from
//! its own generator seeded by `(seed, j)` ([`trajectory_rng`]), so the tape depends on the
//! seed and the layout only; the backward scan sums trajectories in fixed groups of
//! [`GROUP`] and the groups in order, so the gradient is the same bits on any thread count.
//! Map choice is uniform or by given probabilities (Walker's alias table,
//! [`MapSampler`]); the probabilities decide which map a step applies and are not
//! differentiated.

use std::ops::Range;

use rand::{Rng, RngCore};
use rayon::prelude::*;

use crate::chaos::{ChaosGame, MapSampler, is_bounded, trajectory_rng};
use crate::error::{Error, Result};
use crate::model::map3::{DiffMap3, Map3, param_offsets};

/// Trajectories reduced together in the reverse pass; fixed so sums have a fixed order.
pub const GROUP: usize = 16;

/// States `s_0..=s_l` and map indices `i_0..i_{l−1}` of every trajectory
/// (`s_{k+1} = f_{i_k}(s_k)`); states `s_{m+1}..=s_l` are the kept points.
#[derive(Clone, Debug)]
pub struct Tape3 {
    /// `b·(l + 1)` states, trajectory-major.
    pub states: Vec<[f64; 3]>,
    /// `b·l` map indices, trajectory-major.
    pub indices: Vec<u16>,
    /// Number of trajectories b.
    pub trajectories: usize,
    /// Steps per trajectory l.
    pub length: usize,
    /// Dropped steps m.
    pub warmup: usize,
    /// Number of maps the game drew from.
    pub maps: usize,
}

impl Tape3 {
    /// Runs the game of `maps` with `game`'s layout, seeded by `seed` (`game.seed` is
    /// ignored), drawing map `i` with probability `probs[i]` (uniform when `None`).
    /// Refuses an empty code, more than 65 535 maps, bad probabilities and a diverging
    /// trajectory (named, with the step).
    pub fn run<M: Map3>(
        game: &ChaosGame,
        maps: &[M],
        probs: Option<&[f64]>,
        seed: u64,
    ) -> Result<Tape3> {
        game.validate()?;
        if maps.is_empty() {
            return Err(Error::Empty("the code has no maps".into()));
        }
        if maps.len() > u16::MAX as usize {
            return Err(Error::param("maps", "at most 65535 maps"));
        }
        let sampler = match probs {
            Some(p) if p.len() != maps.len() => {
                return Err(Error::Shape(format!(
                    "{} probabilities for {} maps",
                    p.len(),
                    maps.len()
                )));
            }
            Some(p) => MapSampler::new(p)?,
            None => MapSampler::uniform(maps.len()),
        };
        let (b, l) = (game.trajectories, game.length);
        if b.saturating_mul(l + 1) > u32::MAX as usize {
            return Err(Error::param("trajectories", "too many points for one call"));
        }
        let hw = game.start_half_width;
        let mut states = vec![[0.0; 3]; b * (l + 1)];
        let mut indices = vec![0u16; b * l];
        states
            .par_chunks_mut(l + 1)
            .zip(indices.par_chunks_mut(l))
            .enumerate()
            .try_for_each(|(j, (st, ix))| {
                let mut rng = trajectory_rng(seed, j as u64);
                let mut p = if hw > 0.0 {
                    std::array::from_fn(|_| rng.random_range(-hw..hw))
                } else {
                    [0.0; 3]
                };
                st[0] = p;
                for (k, slot) in ix.iter_mut().enumerate() {
                    let i = sampler.pick(rng.next_u64());
                    p = maps[i].apply(p);
                    *slot = i as u16;
                    st[k + 1] = p;
                }
                if !is_bounded(&p) {
                    let step = st.iter().position(|q| !is_bounded(q)).unwrap_or(l);
                    return Err(Error::Divergent {
                        trajectory: j,
                        step,
                    });
                }
                Ok(())
            })?;
        Ok(Tape3 {
            states,
            indices,
            trajectories: b,
            length: l,
            warmup: game.warmup,
            maps: maps.len(),
        })
    }

    /// Kept points per trajectory, `l − m`.
    pub fn kept_per_trajectory(&self) -> usize {
        self.length - self.warmup
    }

    /// Number of kept points, `b·(l − m)`.
    pub fn kept_len(&self) -> usize {
        self.trajectories * self.kept_per_trajectory()
    }

    /// The kept points `s_{m+1}..=s_l` of every trajectory, trajectory-major.
    pub fn kept_points(&self) -> Vec<[f64; 3]> {
        let (l, m) = (self.length, self.warmup);
        self.states
            .chunks_exact(l + 1)
            .flat_map(|st| st[m + 1..].iter().copied())
            .collect()
    }

    /// Backward scan: `∂L/∂θ` of every map, in the flat layout of [`param_offsets`], from
    /// `∂L/∂(kept points)` (the layout of [`Self::kept_points`]).
    ///
    /// Per step `k` (map `i = i_{k−1}`, state `x = s_{k−1}`): `λ += ∂L/∂s_k` if `s_k` is kept,
    /// then `∂L/∂θ_i += (∂f_i/∂θ)(x)ᵀλ` and `λ ← (∂f_i/∂x)(x)ᵀλ` ([`DiffMap::vjp`](crate::model::DiffMap::vjp)).
    pub fn backward<M: DiffMap3>(&self, maps: &[M], grad_points: &[[f64; 3]]) -> Result<Vec<f64>> {
        if maps.len() != self.maps {
            return Err(Error::Shape(format!(
                "the tape was recorded with {} maps but {} were given",
                self.maps,
                maps.len()
            )));
        }
        if grad_points.len() != self.kept_len() {
            return Err(Error::Shape(format!(
                "{} point gradients for {} kept points",
                grad_points.len(),
                self.kept_len()
            )));
        }
        let off = param_offsets(maps);
        let total = off[maps.len()];
        Ok(match M::PARAMS {
            Some(p) if off.iter().enumerate().all(|(i, &o)| o == i * p) => {
                self.scan(maps, grad_points, total, |i| i * p..(i + 1) * p)
            }
            _ => self.scan(maps, grad_points, total, |i| off[i]..off[i + 1]),
        })
    }

    /// The backward scan with map `i`'s gradient in `acc[slot(i)]`.
    fn scan<M: DiffMap3>(
        &self,
        maps: &[M],
        grad_points: &[[f64; 3]],
        total: usize,
        slot: impl Fn(usize) -> Range<usize> + Sync,
    ) -> Vec<f64> {
        let (l, m) = (self.length, self.warmup);
        let kept = l - m;
        let partials: Vec<Vec<f64>> = (0..self.trajectories.div_ceil(GROUP))
            .into_par_iter()
            .map(|g| {
                let mut acc = vec![0.0f64; total];
                for j in g * GROUP..((g + 1) * GROUP).min(self.trajectories) {
                    let st = &self.states[j * (l + 1)..(j + 1) * (l + 1)];
                    let ix = &self.indices[j * l..(j + 1) * l];
                    let gp = &grad_points[j * kept..(j + 1) * kept];
                    let mut lam = [0.0f64; 3];
                    for k in (1..=l).rev() {
                        if k > m {
                            let g = gp[k - m - 1];
                            lam = [lam[0] + g[0], lam[1] + g[1], lam[2] + g[2]];
                        }
                        let i = ix[k - 1] as usize;
                        lam = maps[i].vjp(st[k - 1], lam, &mut acc[slot(i)]);
                    }
                }
                acc
            })
            .collect();
        let mut out = vec![0.0f64; total];
        for p in partials {
            for (t, v) in out.iter_mut().zip(p) {
                *t += v;
            }
        }
        out
    }
}

/// The kept points of the 3-D chaos game of `maps` (no tape kept): what evaluation draws
/// (voxel IoU, Chamfer distance, point clouds), `game.seed` seeding it. Uniform map choice
/// when `probs` is `None`.
pub fn points3<M: Map3>(
    game: &ChaosGame,
    maps: &[M],
    probs: Option<&[f64]>,
) -> Result<Vec<[f64; 3]>> {
    Ok(Tape3::run(game, maps, probs, game.seed)?.kept_points())
}
