//! The words of the maps up to depth K: composed maps level by level, the leaf primitives
//! they carry, and bounding disks that make the tree a bounding-volume hierarchy.
//!
//! Node `j` of level `k` is the word `f_{i₁} ∘ … ∘ f_{i_k}` with `j = i₁·m^{k−1} + … + i_k`;
//! its children `j·m + i` append `f_i` on the inside (`W ∘ f_i`). The paper replaces the
//! figure by its images K times, so the drawing is the base figure under the `m^K` words of
//! level K (the leaves). Each node's disk contains every leaf primitive below it; the disks
//! are built bottom-up from the leaves, so they are exact for any maps — contractive or not —
//! and tighter than a bound from the maps' scales.

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::model::map::Map;
use crate::model::segment::SegmentMap;
use crate::model::segment::complex::{abs, acc, add, cmul, sub};

/// The most leaf primitives a tree may hold (4 194 304: about 240 MiB of maps and disks).
pub const MAX_PRIMITIVES: usize = 1 << 22;

/// Composed maps, leaf primitives and bounding disks of every word up to depth K.
#[derive(Clone, Debug)]
pub struct WordTree {
    maps: Vec<SegmentMap>,
    /// `levels[k]`: the `m^k` words of length k (level 0 is the identity).
    levels: Vec<Vec<SegmentMap>>,
    /// `bounds[k][j]`: `[c_x, c_y, r]`, a disk containing every leaf primitive below node j.
    bounds: Vec<Vec<[f64; 3]>>,
    /// The two points of every leaf primitive, in the plane.
    leaves: Vec<[[f64; 2]; 2]>,
    base: [[f64; 2]; 2],
}

impl WordTree {
    /// The tree of `maps` to depth `depth`, with the base figure on `base`.
    pub fn new(maps: &[SegmentMap], base: [[f64; 2]; 2], depth: usize) -> Result<Self> {
        let m = maps.len();
        if m == 0 {
            return Err(Error::Empty("a word tree needs at least one map".into()));
        }
        let n = (0..depth).try_fold(1usize, |acc, _| acc.checked_mul(m));
        match n {
            Some(n) if n <= MAX_PRIMITIVES => {}
            _ => {
                return Err(Error::param(
                    "depth",
                    format!(
                        "depth {depth} with {m} maps gives {m}^{depth} primitives, more than the {MAX_PRIMITIVES} \
                         the SDF renderer holds; lower the depth"
                    ),
                ));
            }
        }
        // Words of every length, a bounding disk each, and the leaves' points.
        let leaves = n.unwrap_or(usize::MAX) as u64;
        let words = (0..=depth).fold(0u64, |a, k| {
            a.saturating_add((m as u64).saturating_pow(k as u32))
        });
        crate::budget::check_memory(
            &crate::budget::MemoryEstimate::new()
                .with(
                    format!("{words} words to depth {depth} with their bounds"),
                    words.saturating_mul(std::mem::size_of::<SegmentMap>() as u64 + 24),
                )
                .with("leaf primitives", leaves.saturating_mul(32)),
            "the depth (--depth)",
        )?;
        let mut levels = vec![vec![SegmentMap::IDENTITY]];
        for k in 0..depth {
            let prev = &levels[k];
            let mut next = vec![SegmentMap::IDENTITY; prev.len() * m];
            next.par_chunks_mut(m)
                .zip(prev.par_iter())
                .with_min_len(256)
                .for_each(|(children, parent)| {
                    for (c, f) in children.iter_mut().zip(maps) {
                        *c = parent.compose(f);
                    }
                });
            levels.push(next);
        }
        let leaves: Vec<[[f64; 2]; 2]> = levels[depth]
            .par_iter()
            .with_min_len(1024)
            .map(|w| [w.apply(base[0]), w.apply(base[1])])
            .collect();
        let mut bounds = vec![Vec::new(); depth + 1];
        bounds[depth] = leaves
            .par_iter()
            .with_min_len(1024)
            .map(|[a, b]| {
                [
                    0.5 * (a[0] + b[0]),
                    0.5 * (a[1] + b[1]),
                    0.5 * abs(sub(*b, *a)),
                ]
            })
            .collect();
        for k in (0..depth).rev() {
            let below = &bounds[k + 1];
            bounds[k] = below
                .par_chunks(m)
                .with_min_len(256)
                .map(|ch| {
                    let inv = 1.0 / ch.len() as f64;
                    let c = ch
                        .iter()
                        .fold([0.0, 0.0], |s, d| [s[0] + d[0] * inv, s[1] + d[1] * inv]);
                    let r = ch.iter().fold(0.0f64, |r, d| {
                        r.max((d[0] - c[0]).hypot(d[1] - c[1]) + d[2])
                    });
                    [c[0], c[1], r]
                })
                .collect();
        }
        Ok(WordTree {
            maps: maps.to_vec(),
            levels,
            bounds,
            leaves,
            base,
        })
    }

    /// The number of maps m.
    pub fn n_maps(&self) -> usize {
        self.maps.len()
    }

    /// The depth K.
    pub fn depth(&self) -> usize {
        self.levels.len() - 1
    }

    /// The leaf primitives' points.
    pub fn leaves(&self) -> &[[[f64; 2]; 2]] {
        &self.leaves
    }

    /// The bounding disk `[c_x, c_y, r]` of node `j` of level `k`.
    #[inline(always)]
    pub fn bound(&self, k: usize, j: usize) -> [f64; 3] {
        self.bounds[k][j]
    }

    /// The smallest and largest corner of a box containing every leaf primitive.
    pub fn bbox(&self) -> ([f64; 2], [f64; 2]) {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for d in &self.bounds[self.depth()] {
            for c in 0..2 {
                lo[c] = lo[c].min(d[c] - d[2]);
                hi[c] = hi[c].max(d[c] + d[2]);
            }
        }
        (lo, hi)
    }

    /// The chain rule from the leaf primitives' points to the maps and the base figure:
    /// `leaf_grad[j] = [G_a, G_b]` (gradients with respect to leaf j's two points, as
    /// `[a_x, a_y, b_x, b_y]`). Returns `(per-map [G_w, G_t], [G_base_a, G_base_b])`.
    ///
    /// A leaf's points are `W(a₀)`, `W(b₀)` with `W = (w, t)`: `G_w = conj(a₀)·G_a +
    /// conj(b₀)·G_b`, `G_t = G_a + G_b`, `G_a₀ += conj(w)·G_a`. A node `P ∘ f` passes
    /// `G_{P_w} += conj(f_w)·G_w + conj(f_t)·G_t`, `G_{P_t} += G_t` to its parent and
    /// `G_{f_w} += conj(P_w)·G_w`, `G_{f_t} += conj(P_w)·G_t` to the map. The sums run in
    /// a fixed order (level by level, node by node), so the result does not depend on the
    /// thread count.
    pub fn backward(&self, leaf_grad: &[[f64; 4]]) -> (Vec<[f64; 4]>, [[f64; 2]; 2]) {
        let depth = self.depth();
        let m = self.maps.len();
        let [a0, b0] = self.base;
        let mut g_base = [[0.0; 2]; 2];
        // Per node of the current level: [G_w, G_t].
        let mut g: Vec<[f64; 4]> = vec![[0.0; 4]; self.levels[depth].len()];
        for ((gn, lg), w) in g.iter_mut().zip(leaf_grad).zip(&self.levels[depth]) {
            if *lg == [0.0; 4] {
                continue;
            }
            let ga = [lg[0], lg[1]];
            let gb = [lg[2], lg[3]];
            let gw = add(cmul(a0, ga), cmul(b0, gb));
            let gt = add(ga, gb);
            *gn = [gw[0], gw[1], gt[0], gt[1]];
            acc(&mut g_base[0], cmul(w.w, ga));
            acc(&mut g_base[1], cmul(w.w, gb));
        }
        let mut g_maps = vec![[0.0; 4]; m];
        for k in (1..=depth).rev() {
            let parents = &self.levels[k - 1];
            let mut gp = vec![[0.0; 4]; parents.len()];
            for (j, gn) in g.iter().enumerate() {
                if *gn == [0.0; 4] {
                    continue;
                }
                let (pj, i) = (j / m, j % m);
                let p = &parents[pj];
                let f = &self.maps[i];
                let gw = [gn[0], gn[1]];
                let gt = [gn[2], gn[3]];
                let gpw = add(cmul(f.w, gw), cmul(f.t, gt));
                let q = &mut gp[pj];
                q[0] += gpw[0];
                q[1] += gpw[1];
                q[2] += gt[0];
                q[3] += gt[1];
                let gfw = cmul(p.w, gw);
                let gft = cmul(p.w, gt);
                let gm = &mut g_maps[i];
                gm[0] += gfw[0];
                gm[1] += gfw[1];
                gm[2] += gft[0];
                gm[3] += gft[1];
            }
            g = gp;
        }
        (g_maps, g_base)
    }
}
