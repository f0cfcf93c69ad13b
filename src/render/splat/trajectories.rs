//! The chaos game of the fused op, keeping every state for the reverse pass, and the
//! backward scan through each trajectory's maps.
//!
//! Both loops are compiled once per instruction set ([`crate::isa`]): in the
//! [`Isa::Fma`] copy an affine map's four `mul_add`s are four `vfmadd` instructions, where
//! the portable copy calls the runtime's `fma` for each. The tape and the gradients are
//! the same bits either way (tested in `tests/splat.rs`).

use std::ops::Range;

use rand::{Rng, RngCore};
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;

use crate::chaos::{ChaosGame, MapSampler, is_bounded, trajectory_rng};
use crate::error::{Error, Result};
use crate::isa::Isa;
use crate::model::Map2;
use crate::model::map::{DiffMap2, param_offsets};

/// Trajectories reduced together in the reverse pass; fixed so sums have a fixed order.
const GROUP: usize = 16;

/// States `s_0..=s_l` and map indices `i_0..i_{l−1}` of every trajectory
/// (`s_{k+1} = f_{i_k}(s_k)`); states `s_{m+1}..=s_l` are the kept points.
#[derive(Clone, Debug)]
pub struct TrajectoryTape {
    /// `b·(l + 1)` states, trajectory-major.
    pub states: Vec<[f64; 2]>,
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
    /// The instruction set the game ran on (the backward scan runs on it too).
    pub isa: Isa,
}

/// Runs the game seeded by `seed`, drawing maps with probabilities `probs` (uniform when
/// `None`). The probabilities are not differentiated: they only decide which map each step
/// applies. Runs on the instruction set this CPU has best ([`Isa::detect`]).
pub fn run<M: Map2>(
    game: &ChaosGame,
    maps: &[M],
    probs: Option<&[f64]>,
    seed: u64,
) -> Result<TrajectoryTape> {
    run_with_isa(game, maps, probs, seed, Isa::detect())
}

/// [`run`] on instruction set `isa` (an error if this CPU lacks it); the same tape on
/// every instruction set.
pub fn run_with_isa<M: Map2>(
    game: &ChaosGame,
    maps: &[M],
    probs: Option<&[f64]>,
    seed: u64,
    isa: Isa,
) -> Result<TrajectoryTape> {
    let isa = isa.checked()?;
    let (b, l) = (game.trajectories, game.length);
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
    let mut states = vec![[0.0; 2]; b * (l + 1)];
    let mut indices = vec![0u16; b * l];
    let hw = game.start_half_width;
    states
        .par_chunks_mut(l + 1)
        .zip(indices.par_chunks_mut(l))
        .enumerate()
        .try_for_each(|(j, (st, ix))| {
            let rng = trajectory_rng(seed, j as u64);
            let p = match isa {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: `isa` is `Fma` only after `Isa::checked` found AVX2, FMA and BMI1/2.
                Isa::Fma => unsafe { walk_fma(maps, &sampler, hw, rng, st, ix) },
                _ => walk(maps, &sampler, hw, rng, st, ix),
            };
            if !is_bounded(&p) {
                let step = st.iter().position(|q| !is_bounded(q)).unwrap_or(l);
                return Err(Error::Divergent {
                    trajectory: j,
                    step,
                });
            }
            Ok(())
        })?;
    Ok(TrajectoryTape {
        states,
        indices,
        trajectories: b,
        length: l,
        warmup: game.warmup,
        maps: maps.len(),
        isa,
    })
}

/// One trajectory: its start point and `st.len() − 1` steps, states into `st`, map
/// indices into `ix`; returns the last point.
#[inline(always)]
fn walk<M: Map2>(
    maps: &[M],
    sampler: &MapSampler,
    hw: f64,
    mut rng: Xoshiro256PlusPlus,
    st: &mut [[f64; 2]],
    ix: &mut [u16],
) -> [f64; 2] {
    let mut p = if hw > 0.0 {
        [rng.random_range(-hw..hw), rng.random_range(-hw..hw)]
    } else {
        [0.0, 0.0]
    };
    st[0] = p;
    for (k, slot) in ix.iter_mut().enumerate() {
        let i = sampler.pick(rng.next_u64());
        p = maps[i].apply(p);
        *slot = i as u16;
        st[k + 1] = p;
    }
    p
}

/// [`walk`] compiled with AVX2, FMA and BMI1/2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2")]
fn walk_fma<M: Map2>(
    maps: &[M],
    sampler: &MapSampler,
    hw: f64,
    rng: Xoshiro256PlusPlus,
    st: &mut [[f64; 2]],
    ix: &mut [u16],
) -> [f64; 2] {
    walk(maps, sampler, hw, rng, st, ix)
}

impl TrajectoryTape {
    /// Kept points per trajectory, `l − m`.
    pub fn kept_per_trajectory(&self) -> usize {
        self.length - self.warmup
    }

    /// The kept points `s_{m+1}..=s_l` of every trajectory, trajectory-major.
    pub fn kept_points(&self) -> Vec<[f64; 2]> {
        let (l, m) = (self.length, self.warmup);
        self.states
            .chunks_exact(l + 1)
            .flat_map(|st| st[m + 1..].iter().copied())
            .collect()
    }

    /// Backward scan: `∂L/∂θ` of every map, in the flat layout of
    /// [`param_offsets`], from `∂L/∂(kept points)`
    /// (same layout as [`Self::kept_points`]).
    ///
    /// Per step `k` (map `i = i_{k−1}`, state `x = s_{k−1}`): `λ += ∂L/∂s_k` if `s_k` is kept,
    /// then `∂L/∂θ_i += (∂f_i/∂θ)(x)ᵀλ` and `λ ← (∂f_i/∂x)(x)ᵀλ` ([`DiffMap::vjp`](crate::model::DiffMap::vjp)).
    pub fn backward<M: DiffMap2>(&self, maps: &[M], grad_points: &[[f64; 2]]) -> Vec<f64> {
        let off = param_offsets(maps);
        let total = off[maps.len()];
        // Maps of one fixed size (affine: 6) find their slot by a multiplication with a
        // compile-time constant, so the slice length is known and the vjp's bounds checks
        // fold away; otherwise through the offsets table.
        match M::PARAMS {
            Some(p) if off.iter().enumerate().all(|(i, &o)| o == i * p) => {
                self.scan(maps, grad_points, total, |i| i * p..(i + 1) * p)
            }
            _ => self.scan(maps, grad_points, total, |i| off[i]..off[i + 1]),
        }
    }

    /// The backward scan with map `i`'s gradient in `acc[slot(i)]`.
    fn scan<M: DiffMap2>(
        &self,
        maps: &[M],
        grad_points: &[[f64; 2]],
        total: usize,
        slot: impl Fn(usize) -> Range<usize> + Sync,
    ) -> Vec<f64> {
        let isa = self.isa;
        let partials: Vec<Vec<f64>> = (0..self.trajectories.div_ceil(GROUP))
            .into_par_iter()
            .map(|g| {
                let mut acc = vec![0.0f64; total];
                let js = g * GROUP..((g + 1) * GROUP).min(self.trajectories);
                match isa {
                    #[cfg(target_arch = "x86_64")]
                    // SAFETY: the tape's `isa` is `Fma` only after `Isa::checked` found AVX2,
                    // FMA and BMI1/2 on this CPU.
                    Isa::Fma => unsafe {
                        self.scan_group_fma(maps, grad_points, js, &slot, &mut acc)
                    },
                    _ => self.scan_group(maps, grad_points, js, &slot, &mut acc),
                }
                acc
            })
            .collect();
        let mut total = vec![0.0f64; total];
        for p in partials {
            for (t, v) in total.iter_mut().zip(p) {
                *t += v;
            }
        }
        total
    }

    /// The backward scan of trajectories `js`, gradients added to `acc`.
    #[inline(always)]
    fn scan_group<M: DiffMap2>(
        &self,
        maps: &[M],
        grad_points: &[[f64; 2]],
        js: Range<usize>,
        slot: &impl Fn(usize) -> Range<usize>,
        acc: &mut [f64],
    ) {
        let (l, m) = (self.length, self.warmup);
        let kept = l - m;
        for j in js {
            let st = &self.states[j * (l + 1)..(j + 1) * (l + 1)];
            let ix = &self.indices[j * l..(j + 1) * l];
            let gp = &grad_points[j * kept..(j + 1) * kept];
            let mut lam = [0.0f64; 2];
            for k in (1..=l).rev() {
                if k > m {
                    let g = gp[k - m - 1];
                    lam[0] += g[0];
                    lam[1] += g[1];
                }
                let i = ix[k - 1] as usize;
                lam = maps[i].vjp(st[k - 1], lam, &mut acc[slot(i)]);
            }
        }
    }

    /// [`Self::scan_group`] compiled with AVX2, FMA and BMI1/2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2")]
    fn scan_group_fma<M: DiffMap2>(
        &self,
        maps: &[M],
        grad_points: &[[f64; 2]],
        js: Range<usize>,
        slot: &impl Fn(usize) -> Range<usize>,
        acc: &mut [f64],
    ) {
        self.scan_group(maps, grad_points, js, slot, acc)
    }
}
