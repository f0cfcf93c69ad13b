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
    /// The points of `entries`, copied in the same order so a tile reads them sequentially.
    coords: Vec<[T; 2]>,
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

/// Bins points to tiles by a stable counting sort (point order kept within each tile);
/// returns the tile offsets, the point indices and the points in binned order.
fn bin<T: Float + Send + Sync>(uv: &[[T; 2]], g: &Geometry) -> (Vec<usize>, Vec<u32>, Vec<[T; 2]>) {
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
    let mut coords = vec![[T::zero(); 2]; tile_start[n_tiles]];
    for (j, r) in ranges.iter().enumerate() {
        if let Some(r) = r {
            for ty in r[2]..=r[3] {
                for tx in r[0]..=r[1] {
                    let t = ty as usize * g.tiles_x + tx as usize;
                    entries[fill[t]] = j as u32;
                    coords[fill[t]] = uv[j];
                    fill[t] += 1;
                }
            }
        }
    }
    (tile_start, entries, coords)
}

/// Lanes of the inner loops: footprint rows are padded to a multiple of this (with zero
/// weights, which contribute exactly nothing) so the loops vectorise, and reductions keep
/// `LANES` partial sums combined in a fixed order.
const LANES: usize = 8;

/// Gaussian weights `exp(−(i + ½ − x)²/2σ²)` and offsets for pixels `lo..=hi` written to
/// `w` and `d`, padded with zero weights to a multiple of [`LANES`]; returns the padded length.
///
/// Two exponentials per row instead of one per pixel: with `d_{i+1} = d_i + 1`,
/// `w_{i+1} = w_i·r_i` and `r_{i+1} = r_i·q`, where `r_i = exp(−(2d_i + 1)/2σ²)` and
/// `q = exp(−1/σ²)`; over the ≤ 2·radius·σ + 1 pixels of a footprint this stays within a few
/// ulps of the direct formula.
#[inline(always)]
fn weights<T: Float>(
    x: T,
    lo: usize,
    hi: usize,
    inv2s2: T,
    q: T,
    w: &mut [T],
    d: &mut [T],
) -> usize {
    let n = hi - lo + 1;
    let npad = n.div_ceil(LANES) * LANES;
    let half = c::<T>(0.5);
    let two = c::<T>(2.0);
    let mut dx = T::from(lo).unwrap() + half - x;
    let mut wi = (-(dx * dx) * inv2s2).exp();
    let mut r = (-(two * dx + T::one()) * inv2s2).exp();
    for (wk, dk) in w[..n].iter_mut().zip(&mut d[..n]) {
        *dk = dx;
        *wk = wi;
        wi = wi * r;
        r = r * q;
        dx = dx + T::one();
    }
    for k in n..npad {
        w[k] = T::zero();
        d[k] = T::zero();
    }
    npad
}

/// Constants of the footprint, in the working precision.
#[derive(Clone, Copy)]
struct Consts<T> {
    inv2s2: T,
    q: T,
    eps: T,
    inv1me: T,
    amax: T,
    dscale: T,
    norm: T,
}

impl<T: Float> Consts<T> {
    fn new(grid: &SplatGrid, g: &Geometry) -> Self {
        Consts {
            inv2s2: c(0.5 / (grid.sigma * grid.sigma)),
            q: c((-1.0 / (grid.sigma * grid.sigma)).exp()),
            eps: c(g.eps),
            inv1me: c(1.0 / (1.0 - g.eps)),
            amax: c(grid.alpha_max),
            // dα/du = g_raw·(x + ½ − u)/(σ²(1 − ε)).
            dscale: c(1.0 / (grid.sigma * grid.sigma * (1.0 - g.eps))),
            norm: c(1.0 / (grid.supersample * grid.supersample) as f64),
        }
    }
}

/// Where one tile lies.
#[derive(Clone, Copy)]
struct TileGeom {
    ox: usize,
    oy: usize,
    /// Output pixels of the tile (clipped at the image border).
    pw: usize,
    ph: usize,
}

impl Geometry {
    /// Row stride of a tile buffer: the tile plus room for one padded footprint row.
    fn stride(&self) -> usize {
        self.ts + LANES
    }

    fn tile_len(&self) -> usize {
        self.ts * self.stride()
    }

    /// Length of the weight buffers: the widest footprint, padded.
    fn footprint_buf(&self) -> usize {
        (2.0 * self.r).ceil() as usize + 2 + LANES
    }

    fn tile(&self, t: usize, grid: &SplatGrid) -> TileGeom {
        let (tx, ty) = (t % self.tiles_x, t / self.tiles_x);
        TileGeom {
            ox: tx * self.ts,
            oy: ty * self.ts,
            pw: TILE.min(grid.width - tx * TILE),
            ph: TILE.min(grid.height - ty * TILE),
        }
    }

    /// The footprint of point `(u, v)` clipped to a tile, as global pixel ranges.
    #[inline(always)]
    fn clip<T: Float>(&self, p: [T; 2], tg: &TileGeom) -> Option<(usize, usize, usize, usize)> {
        let (u, v) = (p[0].to_f64()?, p[1].to_f64()?);
        let (x0, x1) = footprint(u, self.r, self.gw)?;
        let (y0, y1) = footprint(v, self.r, self.gh)?;
        let (x0, x1) = (x0.max(tg.ox), x1.min(tg.ox + self.ts - 1));
        let (y0, y1) = (y0.max(tg.oy), y1.min(tg.oy + self.ts - 1));
        (x0 <= x1 && y0 <= y1).then_some((x0, x1, y0, y1))
    }
}

/// Splats one tile's points into its buffer (transmittance or density), then pools it.
#[inline(always)]
fn tile_forward_impl<T: Float, const COVERAGE: bool>(
    g: &Geometry,
    k: &Consts<T>,
    tg: &TileGeom,
    s: usize,
    coords: &[[T; 2]],
    buf: &mut [T],
) -> Vec<T> {
    let stride = g.stride();
    let (zero, one) = (T::zero(), T::one());
    let nb = g.footprint_buf();
    let (mut wx, mut wy, mut dx, mut dy) = (
        vec![zero; nb],
        vec![zero; nb],
        vec![zero; nb],
        vec![zero; nb],
    );
    for &p in coords {
        let Some((x0, x1, y0, y1)) = g.clip(p, tg) else {
            continue;
        };
        let npad = weights(p[0], x0, x1, k.inv2s2, k.q, &mut wx, &mut dx);
        weights(p[1], y0, y1, k.inv2s2, k.q, &mut wy, &mut dy);
        let wx = &wx[..npad];
        for (ry, &wyr) in wy[..=y1 - y0].iter().enumerate() {
            let base = (y0 + ry - tg.oy) * stride + (x0 - tg.ox);
            let row = &mut buf[base..base + npad];
            for (b, &wxc) in row.iter_mut().zip(wx) {
                let a = (wxc * wyr - k.eps) * k.inv1me;
                if COVERAGE {
                    let a = if a < zero {
                        zero
                    } else if a > k.amax {
                        k.amax
                    } else {
                        a
                    };
                    *b = *b * (one - a);
                } else {
                    *b = *b + if a < zero { zero } else { a };
                }
            }
        }
    }
    let mut out = vec![zero; tg.pw * tg.ph];
    for py in 0..tg.ph {
        for px in 0..tg.pw {
            let mut sum = zero;
            for sy in 0..s {
                let base = (py * s + sy) * stride + px * s;
                for &b in &buf[base..base + s] {
                    sum = sum + if COVERAGE { one - b } else { b };
                }
            }
            out[py * tg.pw + px] = sum * k.norm;
        }
    }
    out
}

/// Per-point `∂L/∂(u, v)` of one tile's points, in list order.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn tile_backward_impl<T: Float, const COVERAGE: bool>(
    g: &Geometry,
    k: &Consts<T>,
    tg: &TileGeom,
    s: usize,
    width: usize,
    coords: &[[T; 2]],
    trans: &[T],
    grad_image: &[T],
) -> Vec<[f64; 2]> {
    let stride = g.stride();
    let zero = T::zero();
    // H = ∂L/∂I_s, times T for coverage (∂I/∂α_j = T/(1 − α_j)); zero in the padding.
    let mut h = vec![zero; g.tile_len()];
    let (tx0, ty0) = (tg.ox / s, tg.oy / s);
    for py in 0..tg.ph {
        for px in 0..tg.pw {
            let go = grad_image[(ty0 + py) * width + tx0 + px] * k.norm;
            for sy in 0..s {
                let base = (py * s + sy) * stride + px * s;
                for i in base..base + s {
                    h[i] = if COVERAGE { go * trans[i] } else { go };
                }
            }
        }
    }
    let nb = g.footprint_buf();
    let (mut wx, mut wy, mut dx, mut dy) = (
        vec![zero; nb],
        vec![zero; nb],
        vec![zero; nb],
        vec![zero; nb],
    );
    // A plain loop (no closure) so the body inherits the caller's target features.
    let mut out = Vec::with_capacity(coords.len());
    for &p in coords {
        let Some((x0, x1, y0, y1)) = g.clip(p, tg) else {
            out.push([0.0, 0.0]);
            continue;
        };
        let npad = weights(p[0], x0, x1, k.inv2s2, k.q, &mut wx, &mut dx);
        weights(p[1], y0, y1, k.inv2s2, k.q, &mut wy, &mut dy);
        let (gu, gv) = footprint_grad::<T, COVERAGE>(
            k,
            &h,
            (y0 - tg.oy) * stride + (x0 - tg.ox),
            stride,
            &wx[..npad],
            &dx[..npad],
            &wy[..=y1 - y0],
            &dy[..=y1 - y0],
        );
        out.push([
            (gu * k.dscale).to_f64().unwrap_or(0.0),
            (gv * k.dscale).to_f64().unwrap_or(0.0),
        ]);
    }
    out
}

/// `Σ_p H(p)·∂α/∂(u, v)` over one point's footprint (without the `1/σ²(1 − ε)` factor).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn footprint_grad<T: Float, const COVERAGE: bool>(
    k: &Consts<T>,
    h: &[T],
    base: usize,
    stride: usize,
    wx: &[T],
    dx: &[T],
    wy: &[T],
    dy: &[T],
) -> (T, T) {
    let zero = T::zero();
    let one = T::one();
    let npad = wx.len();
    let (mut gu, mut gv) = (zero, zero);
    for (ry, (&wyr, &dyr)) in wy.iter().zip(dy).enumerate() {
        let row = base + ry * stride;
        let hrow = &h[row..row + npad];
        let mut su = [zero; LANES];
        let mut sv = [zero; LANES];
        for ((hc, wc), dc) in hrow
            .chunks_exact(LANES)
            .zip(wx.chunks_exact(LANES))
            .zip(dx.chunks_exact(LANES))
        {
            // Branch-free so the lanes vectorise: compute, then select.
            let mut w = [zero; LANES];
            for l in 0..LANES {
                let gr = wc[l] * wyr;
                let a = (gr - k.eps) * k.inv1me;
                let valid = if COVERAGE {
                    (a > zero) & (a < k.amax)
                } else {
                    a > zero
                };
                let v = if COVERAGE {
                    hc[l] * gr / (one - a)
                } else {
                    hc[l] * gr
                };
                w[l] = if valid { v } else { zero };
            }
            for l in 0..LANES {
                su[l] = su[l] + w[l] * dc[l];
                sv[l] = sv[l] + w[l];
            }
        }
        let (mut ru, mut rv) = (zero, zero);
        for l in 0..LANES {
            ru = ru + su[l];
            rv = rv + sv[l];
        }
        gu = gu + ru;
        gv = gv + rv * dyr;
    }
    (gu, gv)
}

/// Runs `$body` compiled for AVX2 when the CPU has it, else for the baseline target. Both
/// builds execute the same floating-point operations in the same order (Rust never fuses
/// multiply–adds on its own), so results are identical either way.
macro_rules! dispatch {
    ($name:ident, $generic:ident, ($($arg:ident : $ty:ty),*) -> $ret:ty) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        fn $name<T: Float, const COVERAGE: bool>($($arg: $ty),*) -> $ret {
            $generic::<T, COVERAGE>($($arg),*)
        }
    };
}

dispatch!(tile_forward_avx2, tile_forward_impl, (g: &Geometry, k: &Consts<T>, tg: &TileGeom, s: usize, coords: &[[T; 2]], buf: &mut [T]) -> Vec<T>);
dispatch!(tile_backward_avx2, tile_backward_impl, (g: &Geometry, k: &Consts<T>, tg: &TileGeom, s: usize, width: usize, coords: &[[T; 2]], trans: &[T], grad_image: &[T]) -> Vec<[f64; 2]>);

fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

#[allow(clippy::too_many_arguments)]
fn tile_forward<T: Float, const COVERAGE: bool>(
    avx2: bool,
    g: &Geometry,
    k: &Consts<T>,
    tg: &TileGeom,
    s: usize,
    coords: &[[T; 2]],
    buf: &mut [T],
) -> Vec<T> {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: only reached when the CPU reports AVX2.
        return unsafe { tile_forward_avx2::<T, COVERAGE>(g, k, tg, s, coords, buf) };
    }
    let _ = avx2;
    tile_forward_impl::<T, COVERAGE>(g, k, tg, s, coords, buf)
}

#[allow(clippy::too_many_arguments)]
fn tile_backward<T: Float, const COVERAGE: bool>(
    avx2: bool,
    g: &Geometry,
    k: &Consts<T>,
    tg: &TileGeom,
    s: usize,
    width: usize,
    coords: &[[T; 2]],
    trans: &[T],
    grad_image: &[T],
) -> Vec<[f64; 2]> {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: only reached when the CPU reports AVX2.
        return unsafe {
            tile_backward_avx2::<T, COVERAGE>(g, k, tg, s, width, coords, trans, grad_image)
        };
    }
    let _ = avx2;
    tile_backward_impl::<T, COVERAGE>(g, k, tg, s, width, coords, trans, grad_image)
}

/// Forward: pooled image (row-major `height × width`) and the state for the reverse pass.
pub fn forward<T: Float + Send + Sync>(
    grid: &SplatGrid,
    uv: Vec<[T; 2]>,
) -> (Vec<T>, SplatState<T>) {
    let g = grid.geometry();
    let (tile_start, entries, coords) = bin(&uv, &g);
    let s = grid.supersample;
    let tl = g.tile_len();
    let coverage = grid.blend == Blend::Coverage;
    let k = Consts::<T>::new(grid, &g);
    let n_tiles = g.tiles_x * g.tiles_y;
    let avx2 = has_avx2();
    // Each tile's supersampled buffer: transmittance (coverage, kept for the reverse pass)
    // or density (additive, dropped after pooling).
    let mut bufs = vec![if coverage { T::one() } else { T::zero() }; n_tiles * tl];
    let pooled: Vec<Vec<T>> = bufs
        .par_chunks_mut(tl)
        .enumerate()
        .map(|(t, buf)| {
            let tg = g.tile(t, grid);
            let pts = &coords[tile_start[t]..tile_start[t + 1]];
            if coverage {
                tile_forward::<T, true>(avx2, &g, &k, &tg, s, pts, buf)
            } else {
                tile_forward::<T, false>(avx2, &g, &k, &tg, s, pts, buf)
            }
        })
        .collect();
    let mut image = vec![T::zero(); grid.width * grid.height];
    for (t, out) in pooled.iter().enumerate() {
        let tg = g.tile(t, grid);
        for (py, row) in out.chunks_exact(tg.pw).enumerate() {
            let start = (tg.oy / s + py) * grid.width + tg.ox / s;
            image[start..start + tg.pw].copy_from_slice(row);
        }
    }
    if !coverage {
        bufs = Vec::new();
    }
    (
        image,
        SplatState {
            uv,
            tile_start,
            entries,
            coords,
            trans: bufs,
        },
    )
}

/// Reverse: `∂L/∂(u, v)` of every point from `∂L/∂image`.
pub fn backward<T: Float + Send + Sync>(
    grid: &SplatGrid,
    state: &SplatState<T>,
    grad_image: &[T],
) -> Vec<[f64; 2]> {
    let g = grid.geometry();
    let s = grid.supersample;
    let tl = g.tile_len();
    let coverage = grid.blend == Blend::Coverage;
    let k = Consts::<T>::new(grid, &g);
    let n_tiles = g.tiles_x * g.tiles_y;
    let avx2 = has_avx2();
    let (entries, coords, tile_start) = (&state.entries, &state.coords, &state.tile_start);
    let partials: Vec<Vec<[f64; 2]>> = (0..n_tiles)
        .into_par_iter()
        .map(|t| {
            let pts = &coords[tile_start[t]..tile_start[t + 1]];
            if pts.is_empty() {
                return Vec::new();
            }
            let tg = g.tile(t, grid);
            if coverage {
                let trans = &state.trans[t * tl..(t + 1) * tl];
                tile_backward::<T, true>(avx2, &g, &k, &tg, s, grid.width, pts, trans, grad_image)
            } else {
                tile_backward::<T, false>(avx2, &g, &k, &tg, s, grid.width, pts, &[], grad_image)
            }
        })
        .collect();
    let mut guv = vec![[0.0f64; 2]; state.uv.len()];
    for (t, part) in partials.iter().enumerate() {
        for (&j, g) in entries[tile_start[t]..tile_start[t + 1]].iter().zip(part) {
            guv[j as usize][0] += g[0];
            guv[j as usize][1] += g[1];
        }
    }
    guv
}
