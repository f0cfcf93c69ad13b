//! The splat kernel: Gaussian footprints on a supersampled grid, blended, average-pooled;
//! and its reverse pass to per-point gradients. Tiled and deterministic.

use num_traits::Float;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Output pixels per tile side.
const TILE: usize = 16;

/// How splats combine on the supersampled grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Blend {
    /// White over black: `I = 1 − Π(1 − α)`, `α = min(α_max, g)` (the paper's).
    #[default]
    Coverage,
    /// Density: `I = Σ g`.
    Additive,
}

/// The supersampled grid and the Gaussian footprint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplatGrid {
    /// Output width.
    pub width: usize,
    /// Output height.
    pub height: usize,
    /// Supersampling per side.
    pub supersample: usize,
    /// Standard deviation in supersampled pixels.
    pub sigma: f64,
    /// Cut-off radius in units of σ.
    pub radius: f64,
    /// Largest α of one splat (coverage).
    pub alpha_max: f64,
    /// Blend mode.
    pub blend: Blend,
}

/// What the forward pass keeps: points in pixel space, their tile bins and, for coverage,
/// the transmittance `Π(1 − α)` of every supersampled pixel (tile-major).
#[derive(Clone, Debug)]
pub struct SplatState<T> {
    uv: Vec<[T; 2]>,
    /// `tile_start[t]..tile_start[t+1]` indexes `entries` for tile `t`.
    tile_start: Vec<usize>,
    /// Point indices, grouped by tile, in point order within a tile.
    entries: Vec<u32>,
    trans: Vec<T>,
}

impl<T> SplatState<T> {
    /// Points in supersampled pixel coordinates.
    pub fn uv(&self) -> &[[T; 2]] {
        &self.uv
    }
}

#[inline(always)]
fn c<T: Float>(x: f64) -> T {
    T::from(x).expect("finite constant")
}

struct Geometry {
    gw: usize,
    gh: usize,
    ts: usize,
    tiles_x: usize,
    tiles_y: usize,
    r: f64,
    eps: f64,
}

impl SplatGrid {
    fn geometry(&self) -> Geometry {
        let s = self.supersample;
        Geometry {
            gw: self.width * s,
            gh: self.height * s,
            ts: TILE * s,
            tiles_x: self.width.div_ceil(TILE),
            tiles_y: self.height.div_ceil(TILE),
            r: self.radius * self.sigma,
            eps: (-0.5 * self.radius * self.radius).exp(),
        }
    }
}

/// Inclusive pixel range `[lo, hi]` whose centres lie within `r` of `x`, clipped to `[0, n)`.
#[inline(always)]
fn footprint(x: f64, r: f64, n: usize) -> Option<(usize, usize)> {
    let lo = (x - r - 0.5).ceil().max(0.0);
    let hi = (x + r - 0.5).floor().min(n as f64 - 1.0);
    (lo <= hi).then_some((lo as usize, hi as usize))
}

/// Bins points to tiles by a stable counting sort (point order kept within each tile).
fn bin<T: Float + Send + Sync>(uv: &[[T; 2]], g: &Geometry) -> (Vec<usize>, Vec<u32>) {
    let ranges: Vec<Option<[u32; 4]>> = uv
        .par_iter()
        .map(|p| {
            let (u, v) = (p[0].to_f64()?, p[1].to_f64()?);
            if !(u.is_finite() && v.is_finite()) {
                return None;
            }
            let (x0, x1) = footprint(u, g.r, g.gw)?;
            let (y0, y1) = footprint(v, g.r, g.gh)?;
            Some([
                (x0 / g.ts) as u32,
                (x1 / g.ts) as u32,
                (y0 / g.ts) as u32,
                (y1 / g.ts) as u32,
            ])
        })
        .collect();
    let n_tiles = g.tiles_x * g.tiles_y;
    let mut count = vec![0usize; n_tiles + 1];
    for r in ranges.iter().flatten() {
        for ty in r[2]..=r[3] {
            for tx in r[0]..=r[1] {
                count[ty as usize * g.tiles_x + tx as usize + 1] += 1;
            }
        }
    }
    for t in 0..n_tiles {
        count[t + 1] += count[t];
    }
    let tile_start = count.clone();
    let mut fill = count;
    let mut entries = vec![0u32; tile_start[n_tiles]];
    for (j, r) in ranges.iter().enumerate() {
        if let Some(r) = r {
            for ty in r[2]..=r[3] {
                for tx in r[0]..=r[1] {
                    let t = ty as usize * g.tiles_x + tx as usize;
                    entries[fill[t]] = j as u32;
                    fill[t] += 1;
                }
            }
        }
    }
    (tile_start, entries)
}

/// Gaussian weights `exp(−(i + ½ − x)²/2σ²)` for pixels `lo..=hi`, and the offsets.
#[inline(always)]
fn weights<T: Float>(x: T, lo: usize, hi: usize, inv2s2: T, w: &mut Vec<T>, d: &mut Vec<T>) {
    w.clear();
    d.clear();
    let half = c::<T>(0.5);
    for i in lo..=hi {
        let dx = T::from(i).unwrap() + half - x;
        d.push(dx);
        w.push((-(dx * dx) * inv2s2).exp());
    }
}

/// Forward: pooled image (row-major `height × width`) and the state for the reverse pass.
pub fn forward<T: Float + Send + Sync>(grid: &SplatGrid, uv: Vec<[T; 2]>) -> (Vec<T>, SplatState<T>) {
    let g = grid.geometry();
    let (tile_start, entries) = bin(&uv, &g);
    let s = grid.supersample;
    let ts2 = g.ts * g.ts;
    let coverage = grid.blend == Blend::Coverage;
    let inv2s2 = c::<T>(0.5 / (grid.sigma * grid.sigma));
    let eps = c::<T>(g.eps);
    let inv1me = c::<T>(1.0 / (1.0 - g.eps));
    let amax = c::<T>(grid.alpha_max);
    let n_tiles = g.tiles_x * g.tiles_y;
    let mut trans = if coverage {
        vec![T::one(); n_tiles * ts2]
    } else {
        Vec::new()
    };
    let mut acc_additive: Vec<T>;
    // Each tile's supersampled buffer: the transmittance (coverage) or the density (additive).
    let tile_bufs: &mut [T] = if coverage {
        &mut trans
    } else {
        acc_additive = vec![T::zero(); n_tiles * ts2];
        &mut acc_additive
    };
    let pooled: Vec<Vec<T>> = tile_bufs
        .par_chunks_mut(ts2)
        .enumerate()
        .map(|(t, buf)| {
            let (tx, ty) = (t % g.tiles_x, t / g.tiles_x);
            let (ox, oy) = (tx * g.ts, ty * g.ts);
            let (mut wx, mut wy, mut dx, mut dy) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            for &j in &entries[tile_start[t]..tile_start[t + 1]] {
                let [u, v] = uv[j as usize];
                let (uf, vf) = (u.to_f64().unwrap(), v.to_f64().unwrap());
                let (Some((x0, x1)), Some((y0, y1))) = (footprint(uf, g.r, g.gw), footprint(vf, g.r, g.gh)) else {
                    continue;
                };
                let (x0, x1) = (x0.max(ox), x1.min(ox + g.ts - 1));
                let (y0, y1) = (y0.max(oy), y1.min(oy + g.ts - 1));
                if x0 > x1 || y0 > y1 {
                    continue;
                }
                weights(u, x0, x1, inv2s2, &mut wx, &mut dx);
                weights(v, y0, y1, inv2s2, &mut wy, &mut dy);
                for (ry, &wyr) in wy.iter().enumerate() {
                    let row = (y0 + ry - oy) * g.ts + (x0 - ox);
                    let row = &mut buf[row..row + wx.len()];
                    if coverage {
                        for (b, &wxc) in row.iter_mut().zip(&wx) {
                            let a = ((wxc * wyr - eps) * inv1me).max(T::zero()).min(amax);
                            *b = *b * (T::one() - a);
                        }
                    } else {
                        for (b, &wxc) in row.iter_mut().zip(&wx) {
                            *b = *b + ((wxc * wyr - eps) * inv1me).max(T::zero());
                        }
                    }
                }
            }
            // Pool the tile's s×s blocks into its output pixels.
            let (pw, ph) = (TILE.min(grid.width - tx * TILE), TILE.min(grid.height - ty * TILE));
            let norm = c::<T>(1.0 / (s * s) as f64);
            let mut out = vec![T::zero(); pw * ph];
            for py in 0..ph {
                for px in 0..pw {
                    let mut sum = T::zero();
                    for sy in 0..s {
                        let row = &buf[(py * s + sy) * g.ts + px * s..][..s];
                        for &b in row {
                            sum = sum + if coverage { T::one() - b } else { b };
                        }
                    }
                    out[py * pw + px] = sum * norm;
                }
            }
            out
        })
        .collect();
    let mut image = vec![T::zero(); grid.width * grid.height];
    for (t, out) in pooled.iter().enumerate() {
        let (tx, ty) = (t % g.tiles_x, t / g.tiles_x);
        let pw = TILE.min(grid.width - tx * TILE);
        for (py, row) in out.chunks_exact(pw).enumerate() {
            let start = (ty * TILE + py) * grid.width + tx * TILE;
            image[start..start + pw].copy_from_slice(row);
        }
    }
    (
        image,
        SplatState {
            uv,
            tile_start,
            entries,
            trans,
        },
    )
}

/// Reverse: `∂L/∂(u, v)` of every point from `∂L/∂image`.
pub fn backward<T: Float + Send + Sync>(grid: &SplatGrid, state: &SplatState<T>, grad_image: &[T]) -> Vec<[f64; 2]> {
    let g = grid.geometry();
    let s = grid.supersample;
    let ts2 = g.ts * g.ts;
    let coverage = grid.blend == Blend::Coverage;
    let inv2s2 = c::<T>(0.5 / (grid.sigma * grid.sigma));
    let eps = c::<T>(g.eps);
    let inv1me = c::<T>(1.0 / (1.0 - g.eps));
    let amax = c::<T>(grid.alpha_max);
    // dα/du = g_raw·(x + ½ − u)/(σ²(1 − ε)).
    let dscale = c::<T>(1.0 / (grid.sigma * grid.sigma * (1.0 - g.eps)));
    let n_tiles = g.tiles_x * g.tiles_y;
    let (uv, entries, tile_start) = (&state.uv, &state.entries, &state.tile_start);
    let partials: Vec<Vec<[f64; 2]>> = (0..n_tiles)
        .into_par_iter()
        .map(|t| {
            let list = &entries[tile_start[t]..tile_start[t + 1]];
            if list.is_empty() {
                return Vec::new();
            }
            let (tx, ty) = (t % g.tiles_x, t / g.tiles_x);
            let (ox, oy) = (tx * g.ts, ty * g.ts);
            // H = ∂L/∂I_s (·T for coverage, since ∂I/∂α_j = T/(1 − α_j)).
            let norm = c::<T>(1.0 / (s * s) as f64);
            let (pw, ph) = (TILE.min(grid.width - tx * TILE), TILE.min(grid.height - ty * TILE));
            let mut h = vec![T::zero(); ts2];
            for py in 0..ph * s {
                for px in 0..pw * s {
                    let go = grad_image[(ty * TILE + py / s) * grid.width + tx * TILE + px / s] * norm;
                    let k = py * g.ts + px;
                    h[k] = if coverage { go * state.trans[t * ts2 + k] } else { go };
                }
            }
            let (mut wx, mut wy, mut dx, mut dy) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            list.iter()
                .map(|&j| {
                    let [u, v] = uv[j as usize];
                    let (uf, vf) = (u.to_f64().unwrap(), v.to_f64().unwrap());
                    let (Some((x0, x1)), Some((y0, y1))) = (footprint(uf, g.r, g.gw), footprint(vf, g.r, g.gh)) else {
                        return [0.0, 0.0];
                    };
                    let (x0, x1) = (x0.max(ox), x1.min(ox + g.ts - 1));
                    let (y0, y1) = (y0.max(oy), y1.min(oy + g.ts - 1));
                    if x0 > x1 || y0 > y1 {
                        return [0.0, 0.0];
                    }
                    weights(u, x0, x1, inv2s2, &mut wx, &mut dx);
                    weights(v, y0, y1, inv2s2, &mut wy, &mut dy);
                    let (mut gu, mut gv) = (T::zero(), T::zero());
                    for (ry, (&wyr, &dyr)) in wy.iter().zip(&dy).enumerate() {
                        let row = (y0 + ry - oy) * g.ts + (x0 - ox);
                        let hrow = &h[row..row + wx.len()];
                        let (mut su, mut sv) = (T::zero(), T::zero());
                        for ((&hc, &wxc), &dxc) in hrow.iter().zip(&wx).zip(&dx) {
                            let gr = wxc * wyr;
                            let a = (gr - eps) * inv1me;
                            let w = if coverage {
                                if a > T::zero() && a < amax { hc * gr / (T::one() - a) } else { T::zero() }
                            } else if a > T::zero() {
                                hc * gr
                            } else {
                                T::zero()
                            };
                            su = su + w * dxc;
                            sv = sv + w;
                        }
                        gu = gu + su;
                        gv = gv + sv * dyr;
                    }
                    [(gu * dscale).to_f64().unwrap(), (gv * dscale).to_f64().unwrap()]
                })
                .collect()
        })
        .collect();
    let mut guv = vec![[0.0f64; 2]; uv.len()];
    for (t, part) in partials.iter().enumerate() {
        for (&j, g) in entries[tile_start[t]..tile_start[t + 1]].iter().zip(part) {
            guv[j as usize][0] += g[0];
            guv[j as usize][1] += g[1];
        }
    }
    guv
}
