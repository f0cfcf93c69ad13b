//! The splat kernel: Gaussian footprints on a supersampled grid, blended, average-pooled;
//! and its reverse pass to per-point gradients. Tiled and deterministic.

use num_traits::Float;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::isa::Isa;
use crate::math::Real;

/// Tiles span about this many supersampled pixels per side (at least [`MIN_TILE`] output
/// pixels): large enough that few footprints straddle two tiles (each straddling point is
/// splatted once per tile it touches), small enough to spread the work over threads.
const TILE_SUBPIXELS: usize = 64;

/// Fewest output pixels per tile side.
const MIN_TILE: usize = 16;

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
pub struct SplatState<T: SplatReal> {
    uv: Vec<[T; 2]>,
    /// `tile_start[t]..tile_start[t+1]` indexes `entries` for tile `t`.
    tile_start: Vec<usize>,
    /// Point indices, grouped by tile, in point order within a tile.
    entries: Vec<u32>,
    /// The points of `entries`, copied in the same order so a tile reads them sequentially.
    coords: Vec<[T; 2]>,
    /// Tiles with at least one entry, in order; `trans` holds one buffer per used tile.
    used: Vec<usize>,
    trans: Pooled<T>,
    /// The instruction set the forward pass ran on (the reverse pass runs on it too).
    isa: Isa,
}

impl<T: SplatReal> SplatState<T> {
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
    /// Output pixels per tile side.
    tp: usize,
    /// Supersampled pixels per tile side.
    ts: usize,
    tiles_x: usize,
    tiles_y: usize,
    r: f64,
    eps: f64,
}

impl SplatGrid {
    fn geometry(&self) -> Geometry {
        let s = self.supersample;
        let tp = (TILE_SUBPIXELS / s).max(MIN_TILE);
        Geometry {
            gw: self.width * s,
            gh: self.height * s,
            tp,
            ts: tp * s,
            tiles_x: self.width.div_ceil(tp),
            tiles_y: self.height.div_ceil(tp),
            r: self.radius * self.sigma,
            eps: (-0.5 * self.radius * self.radius).exp(),
        }
    }
}

/// Inclusive pixel range `[lo, hi]` whose centres lie within `r` of `x`, clipped to `[0, n)`.
#[inline(always)]
fn footprint(x: f64, r: f64, n: usize) -> Option<(usize, usize)> {
    // Clamp first: far-away points (and non-finite ones, which fail every comparison) must
    // not reach the integer conversions.
    if !(x + r > 0.0 && x - r < n as f64) {
        return None;
    }
    let lo = ceil_i64(x - r - 0.5).max(0);
    let hi = floor_i64(x + r - 0.5).min(n as i64 - 1);
    (lo <= hi).then_some((lo as usize, hi as usize))
}

/// `⌊x⌋` for |x| < 2⁶³ without a libm call (the baseline x86-64 target has no `roundsd`).
#[inline(always)]
fn floor_i64(x: f64) -> i64 {
    let i = x as i64;
    i - i64::from((i as f64) > x)
}

/// `⌈x⌉` for |x| < 2⁶³.
#[inline(always)]
fn ceil_i64(x: f64) -> i64 {
    let i = x as i64;
    i + i64::from((i as f64) < x)
}

/// Bins points to tiles by a stable counting sort (point order kept within each tile);
/// returns the tile offsets, the point indices and the points in binned order.
fn bin<T: SplatReal>(uv: &[[T; 2]], g: &Geometry) -> (Vec<usize>, Vec<u32>, Vec<[T; 2]>) {
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

/// Transmittance below this is set to exactly 0: the pixel is covered, its gradient through
/// `T` is below 1e-18 of the incoming one, and it keeps the arithmetic out of subnormal
/// numbers (which cost ~100 cycles per operation on x86 and dominated the splat's run time).
const TRANSMITTANCE_FLOOR: f64 = 1e-20;

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
#[doc(hidden)]
#[derive(Clone, Copy)]
pub struct Consts<T> {
    pub(super) inv2s2: T,
    q: T,
    pub(super) eps: T,
    pub(super) inv1me: T,
    pub(super) amax: T,
    tmin: T,
    pub(super) dscale: T,
    pub(super) norm: T,
}

impl SplatGrid {
    /// The footprint's constants in f64 and its radius in supersampled pixels: what the GPU
    /// kernels take, computed as the CPU kernel computes them.
    #[cfg(feature = "cuda")]
    pub(super) fn footprint_constants(&self) -> (Consts<f64>, f64) {
        let g = self.geometry();
        (Consts::new(self, &g), g.r)
    }
}

impl<T: Float> Consts<T> {
    fn new(grid: &SplatGrid, g: &Geometry) -> Self {
        Consts {
            inv2s2: c(0.5 / (grid.sigma * grid.sigma)),
            q: c((-1.0 / (grid.sigma * grid.sigma)).exp()),
            eps: c(g.eps),
            inv1me: c(1.0 / (1.0 - g.eps)),
            amax: c(grid.alpha_max),
            tmin: c(TRANSMITTANCE_FLOOR),
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
            pw: self.tp.min(grid.width - tx * self.tp),
            ph: self.tp.min(grid.height - ty * self.tp),
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
fn tile_forward<T: SplatReal, const COVERAGE: bool>(
    isa: Isa,
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
        let base = (y0 - tg.oy) * stride + (x0 - tg.ox);
        T::footprint_forward::<COVERAGE>(isa, buf, base, stride, wx, &wy[..=y1 - y0], k);
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
fn tile_backward<T: SplatReal, const COVERAGE: bool>(
    isa: Isa,
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
        let (gu, gv) = T::footprint_backward::<COVERAGE>(
            isa,
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

/// Buffers at least this long (elements) go back to the pool when dropped.
const POOL_MIN_LEN: usize = 1 << 18;

/// Buffers the pool keeps per precision.
const POOL_SLOTS: usize = 2;

/// A tile buffer that returns to its precision's pool when dropped.
///
/// The coverage transmittance of one call is ~100 MiB at the paper's setting (1024², 5×).
/// Freshly allocated every iteration, it was returned to the kernel and page-faulted back in
/// each time (a quarter of an iteration's time, BENCHMARKS.md §2); recycled, its pages stay
/// resident. The pool holds at most [`POOL_SLOTS`] buffers; [`release_buffers`] empties it.
#[derive(Clone, Debug)]
pub struct Pooled<T: SplatReal>(Vec<T>);

impl<T: SplatReal> Pooled<T> {
    /// A buffer of `len` copies of `fill`, recycled from the pool when one is there.
    fn filled(len: usize, fill: T) -> Self {
        let recycled = if len >= POOL_MIN_LEN {
            T::buffer_pool().lock().ok().and_then(|mut p| p.pop())
        } else {
            None
        };
        let mut v = recycled.unwrap_or_default();
        v.clear();
        v.resize(len, fill);
        Pooled(v)
    }
}

impl<T: SplatReal> std::ops::Deref for Pooled<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        &self.0
    }
}

impl<T: SplatReal> std::ops::DerefMut for Pooled<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        &mut self.0
    }
}

impl<T: SplatReal> Drop for Pooled<T> {
    fn drop(&mut self) {
        if self.0.capacity() >= POOL_MIN_LEN
            && let Ok(mut pool) = T::buffer_pool().lock()
            && pool.len() < POOL_SLOTS
        {
            pool.push(std::mem::take(&mut self.0));
        }
    }
}

pub use crate::math::GpuScalar;

/// Frees the recycled splat buffers of both precisions (they are otherwise kept for the next
/// call).
pub fn release_buffers() {
    if let Ok(mut p) = f32::buffer_pool().lock() {
        p.clear();
    }
    if let Ok(mut p) = f64::buffer_pool().lock() {
        p.clear();
    }
}

/// The float types the kernel runs in, with its two inner loops over one point's footprint
/// (rows padded to a multiple of [`LANES`]). The generic bodies define the arithmetic; `f32`
/// also has AVX2 versions doing the same operations lane by lane in the same order (no fused
/// multiply–adds, the same fixed-order lane reduction), so results are bit-identical
/// whichever runs.
pub trait SplatReal: Real + GpuScalar {
    /// This precision's pool of recycled tile buffers (see [`Pooled`]).
    #[doc(hidden)]
    fn buffer_pool() -> &'static std::sync::Mutex<Vec<Vec<Self>>>;

    /// Blends the footprint `wx ⊗ wy` into `buf` starting at `base` (row stride `stride`).
    #[doc(hidden)]
    #[inline(always)]
    fn footprint_forward<const COVERAGE: bool>(
        _isa: Isa,
        buf: &mut [Self],
        base: usize,
        stride: usize,
        wx: &[Self],
        wy: &[Self],
        k: &Consts<Self>,
    ) {
        for (ry, &wyr) in wy.iter().enumerate() {
            let row = base + ry * stride;
            row_forward_generic::<Self, COVERAGE>(&mut buf[row..row + wx.len()], wx, wyr, k);
        }
    }

    /// `Σ_p H(p)·∂α/∂(u, v)` over the footprint, without the `1/σ²(1 − ε)` factor.
    #[doc(hidden)]
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn footprint_backward<const COVERAGE: bool>(
        _isa: Isa,
        k: &Consts<Self>,
        h: &[Self],
        base: usize,
        stride: usize,
        wx: &[Self],
        dx: &[Self],
        wy: &[Self],
        dy: &[Self],
    ) -> (Self, Self) {
        footprint_backward_generic::<Self, COVERAGE>(k, h, base, stride, wx, dx, wy, dy)
    }
}

impl SplatReal for f64 {
    fn buffer_pool() -> &'static std::sync::Mutex<Vec<Vec<f64>>> {
        static POOL: std::sync::Mutex<Vec<Vec<f64>>> = std::sync::Mutex::new(Vec::new());
        &POOL
    }
}

impl SplatReal for f32 {
    fn buffer_pool() -> &'static std::sync::Mutex<Vec<Vec<f32>>> {
        static POOL: std::sync::Mutex<Vec<Vec<f32>>> = std::sync::Mutex::new(Vec::new());
        &POOL
    }

    #[inline(always)]
    fn footprint_forward<const COVERAGE: bool>(
        isa: Isa,
        buf: &mut [f32],
        base: usize,
        stride: usize,
        wx: &[f32],
        wy: &[f32],
        k: &Consts<f32>,
    ) {
        #[cfg(target_arch = "x86_64")]
        if isa == Isa::Fma {
            // SAFETY: `isa` is `Fma` only when `Isa::detect` or `Isa::checked` found AVX2 (and
            // FMA, BMI1/2) on this CPU; bounds are checked inside.
            return unsafe { avx2::footprint_forward::<COVERAGE>(buf, base, stride, wx, wy, k) };
        }
        let _ = isa;
        for (ry, &wyr) in wy.iter().enumerate() {
            let row = base + ry * stride;
            row_forward_generic::<f32, COVERAGE>(&mut buf[row..row + wx.len()], wx, wyr, k);
        }
    }

    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn footprint_backward<const COVERAGE: bool>(
        isa: Isa,
        k: &Consts<f32>,
        h: &[f32],
        base: usize,
        stride: usize,
        wx: &[f32],
        dx: &[f32],
        wy: &[f32],
        dy: &[f32],
    ) -> (f32, f32) {
        #[cfg(target_arch = "x86_64")]
        if isa == Isa::Fma {
            // SAFETY: as above.
            return unsafe {
                avx2::footprint_backward::<COVERAGE>(k, h, base, stride, wx, dx, wy, dy)
            };
        }
        let _ = isa;
        footprint_backward_generic::<f32, COVERAGE>(k, h, base, stride, wx, dx, wy, dy)
    }
}

#[inline(always)]
fn row_forward_generic<T: Float, const COVERAGE: bool>(
    row: &mut [T],
    wx: &[T],
    wyr: T,
    k: &Consts<T>,
) {
    let (zero, one) = (T::zero(), T::one());
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
            let t = *b * (one - a);
            *b = if t < k.tmin { zero } else { t };
        } else {
            *b = *b + if a < zero { zero } else { a };
        }
    }
}

/// Per lane `l`: `su[l] += w·dx`, `sv[l] += w·dy` over every pixel of the footprint, then
/// the lanes summed in order; `w = H·g/(1 − α)` where `0 < α < α_max` (coverage) or `H·g`
/// where `g > ε` (additive).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn footprint_backward_generic<T: Float, const COVERAGE: bool>(
    k: &Consts<T>,
    h: &[T],
    base: usize,
    stride: usize,
    wx: &[T],
    dx: &[T],
    wy: &[T],
    dy: &[T],
) -> (T, T) {
    let (zero, one) = (T::zero(), T::one());
    let mut su = [zero; LANES];
    let mut sv = [zero; LANES];
    for (ry, (&wyr, &dyr)) in wy.iter().zip(dy).enumerate() {
        let row = base + ry * stride;
        for ((hc, wc), dc) in h[row..row + wx.len()]
            .chunks_exact(LANES)
            .zip(wx.chunks_exact(LANES))
            .zip(dx.chunks_exact(LANES))
        {
            for l in 0..LANES {
                let gr = wc[l] * wyr;
                let a = (gr - k.eps) * k.inv1me;
                let valid = if COVERAGE {
                    a > zero && a < k.amax
                } else {
                    a > zero
                };
                let w = if !valid {
                    zero
                } else if COVERAGE {
                    hc[l] * gr / (one - a)
                } else {
                    hc[l] * gr
                };
                su[l] = su[l] + w * dc[l];
                sv[l] = sv[l] + w * dyr;
            }
        }
    }
    lane_sums(&su, &sv)
}

/// `(Σ su, Σ sv)` over the lanes, in lane order.
#[inline(always)]
fn lane_sums<T: Float>(su: &[T; LANES], sv: &[T; LANES]) -> (T, T) {
    let (mut ru, mut rv) = (T::zero(), T::zero());
    for l in 0..LANES {
        ru = ru + su[l];
        rv = rv + sv[l];
    }
    (ru, rv)
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    //! The f32 footprint loops with AVX2 intrinsics: eight pixels per instruction, the
    //! arithmetic of the generic loops operation for operation.
    use std::arch::x86_64::*;

    use super::{Consts, LANES, lane_sums};

    #[target_feature(enable = "avx2")]
    pub(super) fn footprint_forward<const COVERAGE: bool>(
        buf: &mut [f32],
        base: usize,
        stride: usize,
        wx: &[f32],
        wy: &[f32],
        k: &Consts<f32>,
    ) {
        let n = wx.len() / LANES * LANES;
        let tmin = _mm256_set1_ps(k.tmin);
        assert!(wy.is_empty() || base + (wy.len() - 1) * stride + n <= buf.len());
        let (zero, one) = (_mm256_setzero_ps(), _mm256_set1_ps(1.0));
        let (eps, inv, amax) = (
            _mm256_set1_ps(k.eps),
            _mm256_set1_ps(k.inv1me),
            _mm256_set1_ps(k.amax),
        );
        for (ry, &wyr) in wy.iter().enumerate() {
            let vy = _mm256_set1_ps(wyr);
            let row = base + ry * stride;
            for i in (0..n).step_by(LANES) {
                // SAFETY: row + i + 8 ≤ buf.len() (asserted above) and i + 8 ≤ wx.len().
                unsafe {
                    let w = _mm256_loadu_ps(wx.as_ptr().add(i));
                    let p = buf.as_mut_ptr().add(row + i);
                    let b = _mm256_loadu_ps(p);
                    let a = _mm256_mul_ps(_mm256_sub_ps(_mm256_mul_ps(w, vy), eps), inv);
                    let out = if COVERAGE {
                        let a = _mm256_min_ps(_mm256_max_ps(a, zero), amax);
                        let t = _mm256_mul_ps(b, _mm256_sub_ps(one, a));
                        _mm256_and_ps(t, _mm256_cmp_ps::<_CMP_GE_OQ>(t, tmin))
                    } else {
                        _mm256_add_ps(b, _mm256_max_ps(a, zero))
                    };
                    _mm256_storeu_ps(p, out);
                }
            }
        }
    }

    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn footprint_backward<const COVERAGE: bool>(
        k: &Consts<f32>,
        h: &[f32],
        base: usize,
        stride: usize,
        wx: &[f32],
        dx: &[f32],
        wy: &[f32],
        dy: &[f32],
    ) -> (f32, f32) {
        let n = wx.len().min(dx.len()) / LANES * LANES;
        assert!(wy.is_empty() || base + (wy.len() - 1) * stride + n <= h.len());
        let (zero, one) = (_mm256_setzero_ps(), _mm256_set1_ps(1.0));
        let (eps, inv, amax) = (
            _mm256_set1_ps(k.eps),
            _mm256_set1_ps(k.inv1me),
            _mm256_set1_ps(k.amax),
        );
        let (mut su, mut sv) = (zero, zero);
        for (ry, (&wyr, &dyr)) in wy.iter().zip(dy).enumerate() {
            let vy = _mm256_set1_ps(wyr);
            let vdy = _mm256_set1_ps(dyr);
            let row = base + ry * stride;
            for i in (0..n).step_by(LANES) {
                // SAFETY: row + i + 8 ≤ h.len() (asserted above), i + 8 ≤ wx.len(), dx.len().
                unsafe {
                    let gr = _mm256_mul_ps(_mm256_loadu_ps(wx.as_ptr().add(i)), vy);
                    let a = _mm256_mul_ps(_mm256_sub_ps(gr, eps), inv);
                    let hv = _mm256_loadu_ps(h.as_ptr().add(row + i));
                    let mut valid = _mm256_cmp_ps::<_CMP_GT_OQ>(a, zero);
                    let v = if COVERAGE {
                        valid = _mm256_and_ps(valid, _mm256_cmp_ps::<_CMP_LT_OQ>(a, amax));
                        _mm256_div_ps(_mm256_mul_ps(hv, gr), _mm256_sub_ps(one, a))
                    } else {
                        _mm256_mul_ps(hv, gr)
                    };
                    let w = _mm256_and_ps(v, valid);
                    su = _mm256_add_ps(su, _mm256_mul_ps(w, _mm256_loadu_ps(dx.as_ptr().add(i))));
                    sv = _mm256_add_ps(sv, _mm256_mul_ps(w, vdy));
                }
            }
        }
        let (mut a, mut b) = ([0.0f32; LANES], [0.0f32; LANES]);
        // SAFETY: both arrays hold 8 floats.
        unsafe {
            _mm256_storeu_ps(a.as_mut_ptr(), su);
            _mm256_storeu_ps(b.as_mut_ptr(), sv);
        }
        lane_sums(&a, &b)
    }
}

/// Forward: pooled image (row-major `height × width`) and the state for the reverse pass,
/// on the instruction set this CPU has best ([`Isa::detect`]).
pub fn forward<T: SplatReal>(grid: &SplatGrid, uv: Vec<[T; 2]>) -> (Vec<T>, SplatState<T>) {
    forward_with_isa(grid, uv, Isa::detect())
}

/// [`forward`] on instruction set `isa` (the reverse pass runs on the same one): with
/// [`Isa::Fma`], `f32` footprints are blended eight lanes at a time with AVX2, the same
/// operations in the same order as the portable loops (the same bits). `isa` must be
/// available on this CPU ([`Isa::checked`]); an unavailable one runs the portable loops.
pub fn forward_with_isa<T: SplatReal>(
    grid: &SplatGrid,
    uv: Vec<[T; 2]>,
    isa: Isa,
) -> (Vec<T>, SplatState<T>) {
    let isa = if isa.is_available() {
        isa
    } else {
        Isa::Portable
    };
    let g = grid.geometry();
    let (tile_start, entries, coords) = bin(&uv, &g);
    let s = grid.supersample;
    let tl = g.tile_len();
    let coverage = grid.blend == Blend::Coverage;
    let k = Consts::<T>::new(grid, &g);
    let n_tiles = g.tiles_x * g.tiles_y;
    // Only tiles some footprint touches get a buffer (the others render 0 and have no
    // gradient): the transmittance (coverage, kept for the reverse pass) or the density
    // (additive, dropped after pooling).
    let used: Vec<usize> = (0..n_tiles)
        .filter(|&t| tile_start[t + 1] > tile_start[t])
        .collect();
    let mut bufs = Pooled::filled(used.len() * tl, if coverage { T::one() } else { T::zero() });
    let pooled: Vec<Vec<T>> = bufs
        .par_chunks_mut(tl)
        .zip(used.par_iter())
        .map(|(buf, &t)| {
            let tg = g.tile(t, grid);
            let pts = &coords[tile_start[t]..tile_start[t + 1]];
            if coverage {
                tile_forward::<T, true>(isa, &g, &k, &tg, s, pts, buf)
            } else {
                tile_forward::<T, false>(isa, &g, &k, &tg, s, pts, buf)
            }
        })
        .collect();
    let mut image = vec![T::zero(); grid.width * grid.height];
    for (&t, out) in used.iter().zip(&pooled) {
        let tg = g.tile(t, grid);
        for (py, row) in out.chunks_exact(tg.pw).enumerate() {
            let start = (tg.oy / s + py) * grid.width + tg.ox / s;
            image[start..start + tg.pw].copy_from_slice(row);
        }
    }
    if !coverage {
        bufs = Pooled(Vec::new());
    }
    (
        image,
        SplatState {
            uv,
            tile_start,
            entries,
            coords,
            used,
            trans: bufs,
            isa,
        },
    )
}

/// Reverse: `∂L/∂(u, v)` of every point from `∂L/∂image`.
pub fn backward<T: SplatReal>(
    grid: &SplatGrid,
    state: &SplatState<T>,
    grad_image: &[T],
) -> Vec<[f64; 2]> {
    let g = grid.geometry();
    let s = grid.supersample;
    let tl = g.tile_len();
    let coverage = grid.blend == Blend::Coverage;
    let k = Consts::<T>::new(grid, &g);
    let isa = state.isa;
    let (entries, coords, tile_start) = (&state.entries, &state.coords, &state.tile_start);
    let partials: Vec<Vec<[f64; 2]>> = state
        .used
        .par_iter()
        .enumerate()
        .map(|(slot, &t)| {
            let pts = &coords[tile_start[t]..tile_start[t + 1]];
            let tg = g.tile(t, grid);
            if coverage {
                let trans = &state.trans[slot * tl..(slot + 1) * tl];
                tile_backward::<T, true>(isa, &g, &k, &tg, s, grid.width, pts, trans, grad_image)
            } else {
                tile_backward::<T, false>(isa, &g, &k, &tg, s, grid.width, pts, &[], grad_image)
            }
        })
        .collect();
    let mut guv = vec![[0.0f64; 2]; state.uv.len()];
    for (&t, part) in state.used.iter().zip(&partials) {
        for (&j, g) in entries[tile_start[t]..tile_start[t + 1]].iter().zip(part) {
            guv[j as usize][0] += g[0];
            guv[j as usize][1] += g[1];
        }
    }
    guv
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integer_floor_and_ceil_match_libm() {
        for x in [-3.5, -3.0, -0.2, 0.0, 0.2, 1.0, 2.999, 7.5, 1e9 + 0.5] {
            assert_eq!(floor_i64(x), x.floor() as i64, "floor {x}");
            assert_eq!(ceil_i64(x), x.ceil() as i64, "ceil {x}");
        }
    }

    #[test]
    fn footprints_are_clipped_and_refuse_far_or_nan_points() {
        assert_eq!(footprint(5.2, 1.5, 10), Some((4, 6)));
        assert_eq!(footprint(0.1, 1.5, 10), Some((0, 1)));
        assert_eq!(footprint(-5.0, 1.5, 10), None);
        assert_eq!(footprint(1e30, 1.5, 10), None);
        assert_eq!(footprint(f64::NAN, 1.5, 10), None);
    }

    /// The AVX2 inner loops compute exactly what the generic ones do.
    #[test]
    // Every x86-64 machine this project targets (and CI) has AVX2: without it the test fails
    // rather than passing unchecked.
    #[cfg_attr(
        not(target_arch = "x86_64"),
        ignore = "the AVX2 rows exist on x86-64 only"
    )]
    fn simd_and_generic_rows_agree_bit_for_bit() {
        assert!(
            Isa::Fma.is_available(),
            "this x86-64 CPU has no AVX2: the SIMD rows cannot be checked"
        );
        let grid = SplatGrid {
            width: 8,
            height: 8,
            supersample: 2,
            sigma: 1.3,
            radius: 3.0,
            alpha_max: 0.99,
            blend: Blend::Coverage,
        };
        let g = grid.geometry();
        let k = Consts::<f32>::new(&grid, &g);
        let n = 16;
        let wx: Vec<f32> = (0..n)
            .map(|i| {
                if i < 13 {
                    (-(i as f32 - 6.3).powi(2) / 3.4).exp()
                } else {
                    0.0
                }
            })
            .collect();
        let dx: Vec<f32> = (0..n).map(|i| i as f32 - 6.3).collect();
        let wy = [0.2f32, 0.7, 1.0, 0.5, 0.05];
        let dy = [-2.1f32, -1.1, -0.1, 0.9, 1.9];
        let stride = 24;
        let h: Vec<f32> = (0..stride * 6)
            .map(|i| ((i * 37 % 101) as f32 / 50.0 - 1.0) * 0.3)
            .collect();
        for coverage in [true, false] {
            let mut a: Vec<f32> = (0..stride * 6)
                .map(|i| 0.2 + (i % 7) as f32 / 10.0)
                .collect();
            let mut b = a.clone();
            if coverage {
                f32::footprint_forward::<true>(Isa::Fma, &mut a, 3, stride, &wx, &wy, &k);
                f32::footprint_forward::<true>(Isa::Portable, &mut b, 3, stride, &wx, &wy, &k);
            } else {
                f32::footprint_forward::<false>(Isa::Fma, &mut a, 3, stride, &wx, &wy, &k);
                f32::footprint_forward::<false>(Isa::Portable, &mut b, 3, stride, &wx, &wy, &k);
            }
            assert_eq!(a, b, "forward, coverage = {coverage}");
            let (r1, r2) = if coverage {
                (
                    f32::footprint_backward::<true>(
                        Isa::Fma,
                        &k,
                        &h,
                        3,
                        stride,
                        &wx,
                        &dx,
                        &wy,
                        &dy,
                    ),
                    f32::footprint_backward::<true>(
                        Isa::Portable,
                        &k,
                        &h,
                        3,
                        stride,
                        &wx,
                        &dx,
                        &wy,
                        &dy,
                    ),
                )
            } else {
                (
                    f32::footprint_backward::<false>(
                        Isa::Fma,
                        &k,
                        &h,
                        3,
                        stride,
                        &wx,
                        &dx,
                        &wy,
                        &dy,
                    ),
                    f32::footprint_backward::<false>(
                        Isa::Portable,
                        &k,
                        &h,
                        3,
                        stride,
                        &wx,
                        &dx,
                        &wy,
                        &dy,
                    ),
                )
            };
            assert_eq!(r1, r2, "backward, coverage = {coverage}");
        }
    }

    /// Whole forward and reverse passes on the two instruction sets give the same bits.
    #[test]
    #[cfg_attr(
        not(target_arch = "x86_64"),
        ignore = "the AVX2 rows exist on x86-64 only"
    )]
    fn forward_and_backward_agree_across_instruction_sets() {
        assert!(
            Isa::Fma.is_available(),
            "this x86-64 CPU has no AVX2: the SIMD path cannot be checked"
        );
        for blend in [Blend::Coverage, Blend::Additive] {
            let grid = SplatGrid {
                width: 24,
                height: 20,
                supersample: 3,
                sigma: 1.4,
                radius: 3.0,
                alpha_max: 0.99,
                blend,
            };
            let uv: Vec<[f32; 2]> = (0..900)
                .map(|i| {
                    let t = i as f32 * 0.618;
                    [
                        36.0 + 30.0 * (t * 0.37).sin(),
                        30.0 + 25.0 * (t * 0.23).cos(),
                    ]
                })
                .collect();
            let (ia, sa) = forward_with_isa(&grid, uv.clone(), Isa::Fma);
            let (ib, sb) = forward_with_isa(&grid, uv, Isa::Portable);
            assert_eq!(ia, ib, "forward, {blend:?}");
            let g: Vec<f32> = (0..ia.len())
                .map(|i| ((i * 37 % 101) as f32 / 50.0 - 1.0) * 0.3)
                .collect();
            assert_eq!(
                backward(&grid, &sa, &g),
                backward(&grid, &sb, &g),
                "backward, {blend:?}"
            );
        }
    }
}
