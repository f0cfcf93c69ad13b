//! The SDF raster: for every pixel, the distance to the nearest leaf primitive and which
//! one it is; the paper's image `exp(−d²/σ²)`; the reverse pass from per-pixel distance
//! gradients to the control points.
//!
//! **Forward.** The image is cut into bands of [`TILE`] rows, processed in parallel, and
//! each band into `TILE × TILE` tiles. For a tile, a branch-and-bound walk of the word tree
//! keeps the nodes whose bounding disk can come closer to the tile than the best guaranteed
//! distance `U` found so far (a leaf's disk centre lies on its primitive, so the farthest
//! tile corner from it bounds the distance from every pixel of the tile: `U` shrinks as
//! leaves are met; children are visited nearest first). A subtree whose disk is small next
//! to its distance from the tile is kept whole rather than opened (far from the figure the
//! tile's candidates would otherwise be every leaf of a ring as wide as the tile). The
//! tile's candidates are filtered the same way for each [`BLOCK`] × [`BLOCK`] block of its
//! pixels and sorted by their distance bound; each pixel scans its block's candidates until
//! the bound exceeds its best distance, measuring leaves and descending kept subtrees with
//! its own bound. Nothing is stored per pixel and primitive:
//! memory is the tree plus a distance and an index per pixel. With a cut-off (`U` starts at
//! it), words farther than the cut-off from a tile are never opened, and pixels with no
//! primitive within it read `d = ∞` (pixel 0).
//!
//! **Backward.** Each pixel sends `∂L/∂d` through its nearest primitive (the minimum's
//! gradient is the argmin's) to that leaf's two points; per-leaf sums are taken band after
//! band in pixel order, then [`WordTree::backward`] carries them through the composed words
//! to the maps and the base figure, and the pattern's chain rule to the control points.
//! Every sum has a fixed order: the same bits on any number of threads.
//!
//! **Image formation** (the paper's step 3): pixel `(i, j)` is evaluated at its centre and
//! coloured `exp(−d²/σ²)` with `d` the minimum distance in pixels and σ in pixels; the
//! view says which part of the plane the pixels cover (square pixels, y up).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::image::Image;
use crate::model::segment::{Pattern, PrimitiveKind};
use crate::render::sdf::primitive::{distance, distance_grad};
use crate::render::sdf::words::WordTree;

/// Side of a tile and height of a band, in pixels.
pub const TILE: usize = 16;

/// Side of a block: a tile's candidates are filtered again for each block of pixels.
pub const BLOCK: usize = 4;

/// No primitive within the cut-off.
pub const NONE: u32 = u32::MAX;

/// Which part of the plane an image shows: `width × height` square pixels of side `pixel`,
/// the top-left corner of pixel (0, 0) at `origin`, rows going down (−y).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SdfView {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// The plane point at the top-left corner of the image.
    pub origin: [f64; 2],
    /// The side of a pixel in plane units.
    pub pixel: f64,
}

impl SdfView {
    /// The unit square `[0, 1]²` on `size × size` pixels (what fits see their target as).
    pub fn unit_square(size: usize) -> Self {
        SdfView {
            width: size,
            height: size,
            origin: [0.0, 1.0],
            pixel: 1.0 / size as f64,
        }
    }

    /// A square view centred on the box `lo..hi` whose longest side spans `fill` of it.
    pub fn around(lo: [f64; 2], hi: [f64; 2], size: usize, fill: f64) -> Self {
        let side = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-300) / fill;
        let c = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
        SdfView {
            width: size,
            height: size,
            origin: [c[0] - 0.5 * side, c[1] + 0.5 * side],
            pixel: side / size as f64,
        }
    }

    /// The plane point at the centre of pixel (row `i`, column `j`).
    #[inline(always)]
    pub fn centre(&self, i: usize, j: usize) -> [f64; 2] {
        [
            self.origin[0] + (j as f64 + 0.5) * self.pixel,
            self.origin[1] - (i as f64 + 0.5) * self.pixel,
        ]
    }

    /// Checks sizes and finiteness.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(Error::param(
                "size",
                format!("an image needs pixels, got {}×{}", self.width, self.height),
            ));
        }
        if !(self.pixel.is_finite()
            && self.pixel > 0.0
            && self.origin.iter().all(|v| v.is_finite()))
        {
            return Err(Error::param(
                "view",
                format!(
                    "pixel size must be finite and > 0 and the origin finite, got pixel {} at {:?}",
                    self.pixel, self.origin
                ),
            ));
        }
        Ok(())
    }
}

/// What to draw: recursion depth and, optionally, a cut-off distance.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SdfRenderConfig {
    /// Recursion depth K: the figure is the base under every word of length K.
    pub depth: usize,
    /// Distances beyond this many pixels are not computed (they read as ∞). `None`: the
    /// exact distance at every pixel (what a loss on distance values needs).
    pub cutoff: Option<f64>,
}

/// Counters of one render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SdfStats {
    /// Leaf primitives (`m^K`).
    pub primitives: usize,
    /// Candidates (leaves and far-field subtrees) kept, summed over tiles.
    pub candidates: usize,
    /// Tiles.
    pub tiles: usize,
    /// Candidates kept for the pixels of a block, summed over blocks.
    pub block_candidates: usize,
    /// Blocks.
    pub blocks: usize,
}

/// A rendered distance field: per pixel the distance (in pixels) to the nearest primitive
/// and its leaf index, with what the reverse pass needs.
#[derive(Clone, Debug)]
pub struct SdfRaster {
    view: SdfView,
    kind: PrimitiveKind,
    tree: WordTree,
    dist: Vec<f64>,
    arg: Vec<u32>,
    stats: SdfStats,
}

/// `exp(−d²/σ²)`, 0 for `d = ∞`.
#[inline(always)]
pub fn intensity(d: f64, sigma: f64) -> f64 {
    (-(d * d) / (sigma * sigma)).exp()
}

/// The distance from the box `lo..hi` to the point `c`.
#[inline(always)]
fn rect_dist(lo: [f64; 2], hi: [f64; 2], c: [f64; 2]) -> f64 {
    let dx = (lo[0] - c[0]).max(c[0] - hi[0]).max(0.0);
    let dy = (lo[1] - c[1]).max(c[1] - hi[1]).max(0.0);
    dx.hypot(dy)
}

/// The farthest distance from the box `lo..hi` to the point `c` (at a corner).
#[inline(always)]
fn rect_far(lo: [f64; 2], hi: [f64; 2], c: [f64; 2]) -> f64 {
    let dx = (c[0] - lo[0]).abs().max((hi[0] - c[0]).abs());
    let dy = (c[1] - lo[1]).abs().max((hi[1] - c[1]).abs());
    dx.hypot(dy)
}

/// A candidate of a tile or block: `(lower bound of its distance, level, node)`; a node
/// below the leaves' level stands for its whole subtree.
type Cand = (f64, u32, u32);

/// A node whose bounding radius is below this fraction of its distance to a tile is kept
/// whole as a candidate (each pixel descends it with its own bound) instead of being
/// opened for the tile: far from the figure a tile's candidates would otherwise be every
/// leaf in a ring as wide as the tile.
const FAR_FIELD: f64 = 0.25;

/// An upper bound on the distance from any point of `lo..hi` to the primitives below node
/// `(k, j)` (a leaf's disk centre lies on its primitive; below an inner node there is a
/// primitive within its radius of its centre).
#[inline(always)]
fn node_far(tree: &WordTree, lo: [f64; 2], hi: [f64; 2], k: usize, j: usize) -> f64 {
    let b = tree.bound(k, j);
    let far = rect_far(lo, hi, [b[0], b[1]]);
    if k == tree.depth() { far } else { far + b[2] }
}

/// `(lower bound, k, j)` of the children of node `(k, j)` seen from `lo..hi`, in `kids`.
#[inline(always)]
fn children(tree: &WordTree, lo: [f64; 2], hi: [f64; 2], k: usize, j: usize, kids: &mut Vec<Cand>) {
    let m = tree.n_maps();
    kids.clear();
    for i in 0..m {
        let c = j * m + i;
        let b = tree.bound(k + 1, c);
        kids.push((
            (rect_dist(lo, hi, [b[0], b[1]]) - b[2]).max(0.0),
            (k + 1) as u32,
            c as u32,
        ));
    }
    // Farthest first, so that the nearest is popped first (ties by index).
    kids.sort_unstable_by(|x, y| y.0.total_cmp(&x.0).then(y.2.cmp(&x.2)));
}

/// Candidates of one tile (leaves, and far-field subtrees), sorted by lower bound.
fn tile_candidates(
    tree: &WordTree,
    lo: [f64; 2],
    hi: [f64; 2],
    cap: f64,
    stack: &mut Vec<(u32, u32)>,
    kids: &mut Vec<Cand>,
    out: &mut Vec<Cand>,
) {
    let depth = tree.depth();
    let mut best = cap;
    stack.clear();
    out.clear();
    stack.push((0, 0));
    while let Some((k, j)) = stack.pop() {
        let (k, j) = (k as usize, j as usize);
        let b = tree.bound(k, j);
        let lb = (rect_dist(lo, hi, [b[0], b[1]]) - b[2]).max(0.0);
        if lb > best {
            continue;
        }
        if k == depth || b[2] < FAR_FIELD * lb {
            out.push((lb, k as u32, j as u32));
            best = best.min(node_far(tree, lo, hi, k, j));
            continue;
        }
        children(tree, lo, hi, k, j, kids);
        for &(_, ck, c) in kids.iter() {
            stack.push((ck, c));
        }
    }
    out.retain(|c| c.0 <= best);
    out.sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
}

/// The candidates of a tile that can hold the nearest primitive of some pixel of the block
/// `lo..hi`, sorted by their lower bound.
fn block_candidates(
    tree: &WordTree,
    tile: &[Cand],
    lo: [f64; 2],
    hi: [f64; 2],
    cap: f64,
    out: &mut Vec<Cand>,
) {
    out.clear();
    let mut best = cap;
    for &(tlb, k, j) in tile {
        if tlb > best {
            break;
        }
        let b = tree.bound(k as usize, j as usize);
        let lb = (rect_dist(lo, hi, [b[0], b[1]]) - b[2]).max(0.0);
        if lb > best {
            continue;
        }
        out.push((lb, k, j));
        best = best.min(node_far(tree, lo, hi, k as usize, j as usize));
    }
    out.retain(|c| c.0 <= best);
    out.sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
}

/// The nearest primitive to `p` among the block's candidates, closer than `cap`: a leaf is
/// measured, a subtree descended (its nearest child first, children that cannot beat the
/// best distance so far dropped), anything whose disk is not closer than the best distance
/// so far skipped.
#[inline(always)]
fn nearest(
    tree: &WordTree,
    kind: PrimitiveKind,
    p: [f64; 2],
    block: &[Cand],
    cap: f64,
    stack: &mut Vec<(u32, u32)>,
    kids: &mut Vec<Cand>,
) -> (f64, u32) {
    let depth = tree.depth();
    let leaves = tree.leaves();
    let mut best = cap;
    let mut who = NONE;
    for &(lb, k, j) in block {
        if lb >= best {
            break;
        }
        stack.clear();
        stack.push((k, j));
        while let Some((k, j)) = stack.pop() {
            let (k, j) = (k as usize, j as usize);
            let b = tree.bound(k, j);
            if (p[0] - b[0]).hypot(p[1] - b[1]) - b[2] >= best {
                continue;
            }
            if k == depth {
                let [a, bb] = leaves[j];
                let d = distance(kind, p, a, bb);
                if d < best {
                    best = d;
                    who = j as u32;
                }
                continue;
            }
            // Children whose disks can still beat `best`, the nearest pushed last (popped
            // first); ties by index.
            let m = tree.n_maps();
            kids.clear();
            for i in 0..m {
                let c = j * m + i;
                let cb = tree.bound(k + 1, c);
                let lb = (p[0] - cb[0]).hypot(p[1] - cb[1]) - cb[2];
                if lb < best {
                    kids.push((lb, (k + 1) as u32, c as u32));
                }
            }
            if kids.len() > 1 {
                let near = (0..kids.len())
                    .min_by(|&x, &y| kids[x].0.total_cmp(&kids[y].0).then(x.cmp(&y)))
                    .unwrap_or(0);
                let last = kids.len() - 1;
                kids.swap(near, last);
            }
            for &(_, ck, c) in kids.iter() {
                stack.push((ck, c));
            }
        }
    }
    (best, who)
}

impl SdfRaster {
    /// Draws `pattern` into `view`.
    pub fn render(pattern: &Pattern, view: &SdfView, cfg: &SdfRenderConfig) -> Result<Self> {
        view.validate()?;
        if let Some(c) = cfg.cutoff
            && !(c.is_finite() && c > 0.0)
        {
            return Err(Error::param(
                "cutoff",
                format!("must be > 0 pixels (or absent), got {c}"),
            ));
        }
        let tree = WordTree::new(&pattern.maps()?, pattern.base_points(), cfg.depth)?;
        let kind = pattern.base().kind;
        let (w, h) = (view.width, view.height);
        let cap = cfg.cutoff.map_or(f64::INFINITY, |c| c * view.pixel);
        let mut dist = vec![f64::INFINITY; w * h];
        let mut arg = vec![NONE; w * h];
        let leaves = tree.leaves();
        let counts: Vec<(usize, usize, usize, usize)> = dist
            .par_chunks_mut(TILE * w)
            .zip(arg.par_chunks_mut(TILE * w))
            .enumerate()
            .map(|(band, (dband, aband))| {
                let i0 = band * TILE;
                let rows = dband.len() / w;
                let mut stack = Vec::new();
                let mut kids = Vec::new();
                let mut cands = Vec::new();
                let mut block = Vec::new();
                let (mut n_cand, mut n_tiles, mut n_block, mut n_blocks) = (0, 0, 0, 0);
                let span = |i0: usize, j0: usize, rows: usize, cols: usize| {
                    let top_left = view.centre(i0, j0);
                    let bottom_right = view.centre(i0 + rows - 1, j0 + cols - 1);
                    (
                        [top_left[0], bottom_right[1]],
                        [bottom_right[0], top_left[1]],
                    )
                };
                for j0 in (0..w).step_by(TILE) {
                    let cols = TILE.min(w - j0);
                    let (lo, hi) = span(i0, j0, rows, cols);
                    tile_candidates(&tree, lo, hi, cap, &mut stack, &mut kids, &mut cands);
                    n_cand += cands.len();
                    n_tiles += 1;
                    for bi in (0..rows).step_by(BLOCK) {
                        let brows = BLOCK.min(rows - bi);
                        for bj in (0..cols).step_by(BLOCK) {
                            let bcols = BLOCK.min(cols - bj);
                            let (blo, bhi) = span(i0 + bi, j0 + bj, brows, bcols);
                            block_candidates(&tree, &cands, blo, bhi, cap, &mut block);
                            n_block += block.len();
                            n_blocks += 1;
                            for di in bi..bi + brows {
                                for dj in j0 + bj..j0 + bj + bcols {
                                    let p = view.centre(i0 + di, dj);
                                    let (best, who) =
                                        nearest(&tree, kind, p, &block, cap, &mut stack, &mut kids);
                                    if who != NONE {
                                        dband[di * w + dj] = best / view.pixel;
                                        aband[di * w + dj] = who;
                                    }
                                }
                            }
                        }
                    }
                }
                (n_cand, n_tiles, n_block, n_blocks)
            })
            .collect();
        let stats = SdfStats {
            primitives: leaves.len(),
            candidates: counts.iter().map(|c| c.0).sum(),
            tiles: counts.iter().map(|c| c.1).sum(),
            block_candidates: counts.iter().map(|c| c.2).sum(),
            blocks: counts.iter().map(|c| c.3).sum(),
        };
        Ok(SdfRaster {
            view: *view,
            kind,
            tree,
            dist,
            arg,
            stats,
        })
    }

    /// The view.
    pub fn view(&self) -> &SdfView {
        &self.view
    }

    /// Per pixel, row-major: the distance in pixels to the nearest primitive (∞ beyond the
    /// cut-off).
    pub fn distances(&self) -> &[f64] {
        &self.dist
    }

    /// Per pixel, the nearest leaf ([`NONE`] beyond the cut-off).
    pub fn nearest(&self) -> &[u32] {
        &self.arg
    }

    /// The word tree drawn.
    pub fn tree(&self) -> &WordTree {
        &self.tree
    }

    /// Counters.
    pub fn stats(&self) -> SdfStats {
        self.stats
    }

    /// The paper's image `exp(−d²/σ²)` (σ in pixels).
    pub fn image(&self, sigma: f64) -> Vec<f64> {
        self.dist
            .par_iter()
            .with_min_len(4096)
            .map(|&d| intensity(d, sigma))
            .collect()
    }

    /// [`SdfRaster::image`] as the stack's [`Image`] (grey, at the raster's f64): a target
    /// drawn by a pattern, as a problem takes one.
    pub fn to_image(&self, sigma: f64) -> Image<f64> {
        Image {
            width: self.view.width as u32,
            height: self.view.height as u32,
            channels: 1,
            values: self.image(sigma),
        }
    }

    /// Pulls `∂L/∂image` back to `∂L/∂d`: `∂ exp(−d²/σ²)/∂d = −2d/σ²·exp(−d²/σ²)`.
    pub fn image_backward(&self, sigma: f64, grad_image: &[f64]) -> Vec<f64> {
        self.dist
            .par_iter()
            .zip(grad_image.par_iter())
            .with_min_len(4096)
            .map(|(&d, &g)| {
                if d.is_finite() {
                    g * (-2.0 * d / (sigma * sigma)) * intensity(d, sigma)
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// The gradient with respect to `pattern`'s control points (flat, as
    /// [`Pattern::flat_points`]) of a loss whose gradient with respect to the per-pixel
    /// distances (in pixels) is `grad_dist`. `pattern` must be the one rendered.
    pub fn backward(&self, pattern: &Pattern, grad_dist: &[f64]) -> Result<Vec<f64>> {
        let (w, h) = (self.view.width, self.view.height);
        if grad_dist.len() != w * h {
            return Err(Error::Shape(format!(
                "{} distance gradients for a {w}×{h} raster",
                grad_dist.len()
            )));
        }
        let leaves = self.tree.leaves();
        let inv_px = 1.0 / self.view.pixel;
        let per_band: Vec<Vec<(u32, [f64; 4])>> = grad_dist
            .par_chunks(TILE * w)
            .zip(self.arg.par_chunks(TILE * w))
            .enumerate()
            .map(|(band, (gband, aband))| {
                let mut out = Vec::new();
                for (q, (&g, &leaf)) in gband.iter().zip(aband).enumerate() {
                    if leaf == NONE || g == 0.0 {
                        continue;
                    }
                    let p = self.view.centre(band * TILE + q / w, q % w);
                    let [a, b] = leaves[leaf as usize];
                    let (_, ga, gb) = distance_grad(self.kind, p, a, b);
                    let s = g * inv_px;
                    out.push((leaf, [s * ga[0], s * ga[1], s * gb[0], s * gb[1]]));
                }
                out
            })
            .collect();
        let mut leaf_grad = vec![[0.0; 4]; leaves.len()];
        for band in &per_band {
            for (leaf, g) in band {
                let l = &mut leaf_grad[*leaf as usize];
                for c in 0..4 {
                    l[c] += g[c];
                }
            }
        }
        let (g_maps, g_base) = self.tree.backward(&leaf_grad);
        let mut out = vec![0.0; 2 * pattern.points().len()];
        pattern.maps_backward(&g_maps, &mut out);
        let base = pattern.base().points;
        for (k, g) in base.iter().zip(g_base) {
            out[2 * k] += g[0];
            out[2 * k + 1] += g[1];
        }
        Ok(out)
    }
}
