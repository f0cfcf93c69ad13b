//! The encoder's search: for every texel of the source, the candidate blocks of the reduced
//! texture R inside its window scored against the texel's range block, the best kept per
//! texel (`TopK`), one row at a time (`encode` runs the rows in parallel), with AVX2 kernels
//! when the encoding runs on [`Isa::Fma`] (decided once per encoding, `ifslab::isa`).

use std::cmp::Ordering;
use std::sync::atomic::{AtomicU64, Ordering as AtomicOrdering};

use ifslab::isa::Isa;

use super::{EncoderConfig, HALF_MAX, HALF_MIN, MAX_TOTAL_CANDIDATES, Matching, SearchGrid};
use crate::error::{Error, Result};
use crate::problems::fractal_coding::texture::Texture;

/// The candidate blocks at positions (px + s·i, py + s·j) of R, as structure-of-arrays planes.
struct Lattice {
    px: usize,
    py: usize,
    /// Positions per row.
    nx: usize,
    /// `NP` planes (see the module docs), each `nx × ny`.
    d: Vec<Vec<f32>>,
    /// ‖d‖² (raw) or ‖d̃‖² (mean-removed) over the four texels and every channel.
    q: Vec<f32>,
}

/// The lattices of a grid: one for `all` and `even`, four parity classes for `even-offset`.
pub(super) struct Planes {
    stride: usize,
    lattices: Vec<Lattice>,
    /// Planes per lattice: 4 or 3 per channel.
    np: usize,
    /// The instruction set the scoring loops run on (decided once per encoding).
    isa: Isa,
}

impl Planes {
    /// The planes of `r`; the search scores them on `isa` (available on this CPU).
    pub(super) fn new(r: &Texture, cfg: &EncoderConfig, isa: Isa) -> Self {
        let s = cfg.grid.stride();
        let classes: &[(usize, usize)] = match cfg.grid {
            SearchGrid::All | SearchGrid::Even => &[(0, 0)],
            SearchGrid::EvenOffset => &[(0, 0), (1, 0), (0, 1), (1, 1)],
        };
        let nc = r.channels();
        let per = match cfg.matching {
            Matching::Raw => 4,
            Matching::MeanRemoved => 3,
        };
        let count = |p: usize, n: usize| if p + 2 <= n { (n - 2 - p) / s + 1 } else { 0 };
        let lattices = classes
            .iter()
            .map(|&(px, py)| {
                let (nx, ny) = (count(px, r.width()), count(py, r.height()));
                let mut d = vec![vec![0.0f32; nx * ny]; per * nc];
                let mut q = vec![0.0f32; nx * ny];
                for j in 0..ny {
                    for i in 0..nx {
                        let k = j * nx + i;
                        let (x, y) = (px + s * i, py + s * j);
                        let mut qq = 0.0f32;
                        for c in 0..nc {
                            let v = block(r, x, y, c);
                            let m = match cfg.matching {
                                Matching::Raw => 0.0,
                                Matching::MeanRemoved => 0.25 * (v[0] + v[1] + v[2] + v[3]),
                            };
                            for (jj, &vj) in v.iter().enumerate() {
                                let t = vj - m;
                                qq += t * t;
                                if jj < per {
                                    d[per * c + jj][k] = t;
                                }
                            }
                        }
                        q[k] = qq;
                    }
                }
                Lattice { px, py, nx, d, q }
            })
            .collect();
        Planes {
            stride: s,
            lattices,
            np: per * nc,
            isa,
        }
    }

    fn lattice(&self, grid: SearchGrid, cx: usize, cy: usize) -> &Lattice {
        let (px, py) = grid.class(cx, cy);
        self.lattices
            .iter()
            .find(|l| (l.px, l.py) == (px, py))
            .expect("a lattice for every parity class of the grid")
    }
}

/// The 2×2 block of channel `c` at top-left `(x, y)`, in the order (0,0), (1,0), (0,1), (1,1).
pub(super) fn block(t: &Texture, x: usize, y: usize, c: usize) -> [f32; 4] {
    [
        t.get(x, y, c),
        t.get(x + 1, y, c),
        t.get(x, y + 1, c),
        t.get(x + 1, y + 1, c),
    ]
}

/// The inclusive range of positions of R along one axis that texel coordinate `c` may use:
/// within ±window, inside R (a block needs two texels), and for the even grids with half
/// relative coordinate in [HALF_MIN, HALF_MAX]; then the lattice indices (p + s·i) inside it.
fn axis_range(
    cfg: &EncoderConfig,
    c: usize,
    n: usize,
    p: usize,
    s: usize,
) -> Option<(usize, usize)> {
    let c = c as i64;
    let win = i64::from(cfg.window);
    let mut lo = (c - win).max(0);
    let mut hi = (c + win).min(n as i64 - 2);
    if let Some(b) = cfg.grid.half_base(c as usize) {
        let b = b as i64;
        lo = lo.max(b + 2 * i64::from(HALF_MIN));
        hi = hi.min(b + 2 * i64::from(HALF_MAX));
    }
    let (p, s) = (p as i64, s as i64);
    let ilo = (lo - p + s - 1).div_euclid(s).max(0);
    let ihi = (hi - p).div_euclid(s);
    (ilo <= ihi).then_some((ilo as usize, ihi as usize))
}

/// One texel's candidates, best first.
pub(super) struct TexelResult {
    pub(super) coords: Vec<u32>,
    pub(super) offsets: Vec<f32>,
    pub(super) sse: Vec<f32>,
    pub(super) scores: Vec<f32>,
    pub(super) scored: u64,
}

/// A texel's range block, prepared for scoring: the weights w of ‖d‖² − 2 w·d per plane.
struct Range {
    w: [f32; 12],
    /// ‖r‖² (raw) or ‖r̃‖² (mean-removed): the score's constant part, added back at the end.
    norm: f32,
}

fn range_block(s: &Texture, cfg: &EncoderConfig, cx: usize, cy: usize) -> Range {
    let mut w = [0.0f32; 12];
    let mut norm = 0.0f32;
    for c in 0..s.channels() {
        let v = block(s, 2 * cx, 2 * cy, c);
        match cfg.matching {
            Matching::Raw => {
                for j in 0..4 {
                    w[4 * c + j] = v[j];
                    norm += v[j] * v[j];
                }
            }
            Matching::MeanRemoved => {
                let m = 0.25 * (v[0] + v[1] + v[2] + v[3]);
                let t3 = v[3] - m;
                for j in 0..3 {
                    w[3 * c + j] = (v[j] - m) - t3;
                }
                norm += v.iter().map(|x| (x - m) * (x - m)).sum::<f32>();
            }
        }
    }
    Range { w, norm }
}

/// A candidate's ordering key: (score, Manhattan distance to the centre, index in R).
type Key = (f32, u32, u32);

fn key_cmp(a: &Key, b: &Key) -> Ordering {
    a.0.total_cmp(&b.0).then((a.1, a.2).cmp(&(b.1, b.2)))
}

fn key_lt(a: &Key, b: &Key) -> bool {
    key_cmp(a, b) == Ordering::Less
}

/// The candidate set Ω of one texel while its search runs: every key that may still end up in
/// {best} ∪ {score < best + ΔE_max}, capped to the `cap` smallest keys.
///
/// Keys are collected unsorted and compacted (filtered by the current best, sorted, truncated
/// to the cap) when the list doubles, so an uncapped Ω of any size costs O(n log n).
struct TopK {
    cap: usize,
    delta: f32,
    best: Option<Key>,
    /// Once `cap` keys are known: the cap-th smallest, which later keys must beat.
    kth: Option<Key>,
    items: Vec<Key>,
    compact_at: usize,
}

impl TopK {
    fn new(cap: Option<usize>, delta: f32) -> Self {
        let cap = cap.unwrap_or(usize::MAX);
        TopK {
            cap,
            delta,
            best: None,
            kth: None,
            items: Vec::new(),
            compact_at: cap.saturating_mul(2).clamp(2, 256),
        }
    }

    /// Whether a key can belong to the final set, given what has been seen so far. Monotone:
    /// a key that is refused refuses every larger key too.
    fn admits(&self, k: &Key) -> bool {
        let Some(b) = self.best else {
            return true;
        };
        (key_lt(k, &b) || k.0 < b.0 + self.delta) && self.kth.is_none_or(|t| key_lt(k, &t))
    }

    /// Scores above this are never admitted.
    fn threshold(&self) -> f32 {
        let Some(b) = self.best else {
            return f32::INFINITY;
        };
        let t = b.0 + self.delta;
        self.kth.map_or(t, |k| t.min(k.0))
    }

    fn push(&mut self, k: Key) {
        if !self.admits(&k) {
            return;
        }
        if self.best.is_none_or(|b| key_lt(&k, &b)) {
            self.best = Some(k);
        }
        self.items.push(k);
        if self.items.len() >= self.compact_at {
            self.compact();
        }
    }

    fn compact(&mut self) {
        let Some(b) = self.best else {
            return;
        };
        let delta = self.delta;
        self.items.retain(|k| *k == b || k.0 < b.0 + delta);
        self.items.sort_unstable_by(key_cmp);
        if self.items.len() >= self.cap {
            self.items.truncate(self.cap);
            self.kth = self.items.last().copied();
        }
        self.compact_at = (2 * self.items.len()).max(self.compact_at);
    }

    /// The final set, best first.
    fn finish(mut self) -> Vec<Key> {
        self.compact();
        self.items
    }
}

/// Texels searched together (one pass over the candidates scores a whole tile).
const TILE: usize = 4;
/// Lanes of the vectorised candidate loop.
const LANES: usize = 8;

/// Searches row `cy` of R; `kept` counts the candidates kept by all rows so far, so that an
/// Ω too large for memory is refused (the total only grows, so whether it is refused does not
/// depend on the order rows finish in).
pub(super) fn search_row(
    s: &Texture,
    r: &Texture,
    planes: &Planes,
    cfg: &EncoderConfig,
    cy: usize,
    kept: &AtomicU64,
) -> Result<Vec<TexelResult>> {
    match planes.isa {
        Isa::Fma => search_row_on::<true>(s, r, planes, cfg, cy, kept),
        Isa::Portable => search_row_on::<false>(s, r, planes, cfg, cy, kept),
    }
}

/// [`search_row`] with the scoring loops of [`search_tile`]`::<AVX2>`.
fn search_row_on<const AVX2: bool>(
    s: &Texture,
    r: &Texture,
    planes: &Planes,
    cfg: &EncoderConfig,
    cy: usize,
    kept: &AtomicU64,
) -> Result<Vec<TexelResult>> {
    let wr = r.width();
    let mut out: Vec<Option<TexelResult>> = (0..wr).map(|_| None).collect();
    let max_nx = planes.lattices.iter().map(|l| l.nx).max().unwrap_or(0);
    let mut buf = vec![0.0f32; TILE * (max_nx + LANES)];
    // Texels of a tile share a lattice: neighbours, or every other texel for even-offset.
    let step = if cfg.grid == SearchGrid::EvenOffset {
        2
    } else {
        1
    };
    for first in 0..step {
        let mut cx = first;
        while cx < wr {
            let t = if cx + (TILE - 1) * step < wr { TILE } else { 1 };
            let tile: Vec<usize> = (0..t).map(|i| cx + i * step).collect();
            let tops = search_tile::<AVX2>(s, planes, cfg, &tile, cy, &mut buf)?;
            for (&x, (top, scored)) in tile.iter().zip(tops) {
                let res = finish(s, r, cfg, x, cy, top, scored);
                let n = res.coords.len() as u64;
                if kept.fetch_add(n, AtomicOrdering::Relaxed) + n > MAX_TOTAL_CANDIDATES {
                    return Err(Error::InvalidInput(format!(
                        "the candidate sets Ω hold more than {MAX_TOTAL_CANDIDATES} candidates in \
                         all (ΔE_max {} keeps too many blocks of this texture): set \
                         max_candidates or lower delta_e_max",
                        cfg.delta_e_max
                    )));
                }
                out[x] = Some(res);
            }
            cx += t * step;
        }
    }
    Ok(out
        .into_iter()
        .map(|o| o.expect("every texel of the row searched"))
        .collect())
}

/// Searches the texels `tile` (same row `cy`, same lattice); returns their candidate sets and
/// the number of candidates each scored.
///
/// `AVX2` picks the scoring loops: true only where the encoding's instruction set is
/// [`Isa::Fma`] (checked available on this CPU).
fn search_tile<const AVX2: bool>(
    s: &Texture,
    planes: &Planes,
    cfg: &EncoderConfig,
    tile: &[usize],
    cy: usize,
    buf: &mut [f32],
) -> Result<Vec<(TopK, u64)>> {
    let lat = planes.lattice(cfg.grid, tile[0], cy);
    let st = planes.stride;
    let (wr, hr) = (s.width() / 2, s.height() / 2);
    let no_block = |cx: usize| {
        Error::InvalidInput(format!(
            "texel ({cx}, {cy}) of the {wr}×{hr} reduced texture has no candidate block in grid `{}` \
             with window {}: widen the window or use a larger texture",
            cfg.grid, cfg.window
        ))
    };
    let (jlo, jhi) = axis_range(cfg, cy, hr, lat.py, st).ok_or_else(|| no_block(tile[0]))?;
    let mut win = Vec::with_capacity(tile.len());
    for &cx in tile {
        win.push(axis_range(cfg, cx, wr, lat.px, st).ok_or_else(|| no_block(cx))?);
    }
    let ulo = win.iter().map(|w| w.0).min().expect("a non-empty tile");
    let uhi = win.iter().map(|w| w.1).max().expect("a non-empty tile");
    let len = uhi + 1 - ulo;
    let stride = lat.nx + LANES;
    let ranges: Vec<Range> = tile.iter().map(|&cx| range_block(s, cfg, cx, cy)).collect();
    let lo: Vec<u32> = win.iter().map(|w| (w.0 - ulo) as u32).collect();
    let hi: Vec<u32> = win.iter().map(|w| (w.1 - ulo) as u32).collect();
    let mut tops: Vec<(TopK, u64)> = tile
        .iter()
        .map(|_| (TopK::new(cfg.max_candidates, cfg.delta_e_max), 0))
        .collect();
    let k = cfg.distance.scale();
    let (cy0, pos) = (k * cy, |j: usize| lat.py + st * j);
    // Rows nearest to the distance centre first, so that the best is found early; the result
    // does not depend on this order.
    let mut rows: Vec<usize> = (jlo..=jhi).collect();
    rows.sort_by_key(|&j| (pos(j).abs_diff(cy0), j));
    let mut mins = [f32::INFINITY; TILE];
    for j in rows {
        let y = pos(j);
        let base = j * lat.nx + ulo;
        let job = RowJob {
            d: &lat.d,
            q: &lat.q[base..base + len],
            base,
            len,
            x0: (lat.px + st * ulo) as f32,
            xstep: st as f32,
            ranges: &ranges,
            lo: &lo,
            hi: &hi,
            cx: tile.iter().map(|&cx| (k * cx) as f32).collect(),
            beta: cfg.beta,
            dy: y.abs_diff(cy0) as f32,
        };
        score_row::<AVX2>(&job, planes.np, buf, stride, &mut mins);
        for (i, (top, scored)) in tops.iter_mut().enumerate() {
            let (lo, hi) = (lo[i] as usize, hi[i] as usize);
            *scored += (hi + 1 - lo) as u64;
            let x_first = lat.px + st * (ulo + lo);
            let bound = (mins[i], y.abs_diff(cy0) as u32, (y * wr + x_first) as u32);
            if !top.admits(&bound) {
                continue;
            }
            // Only chunks of eight that hold a qualifying score are scanned one by one.
            let row = &buf[i * stride + lo..i * stride + hi + 1];
            let cxk = k * tile[i];
            for (n, chunk) in row.chunks(LANES).enumerate() {
                if chunk_min(chunk) > top.threshold() {
                    continue;
                }
                for (jj, &sc) in chunk.iter().enumerate() {
                    if sc <= top.threshold() {
                        let x = lat.px + st * (ulo + lo + n * LANES + jj);
                        let man = (x.abs_diff(cxk) + y.abs_diff(cy0)) as u32;
                        top.push((sc, man, (y * wr + x) as u32));
                    }
                }
            }
        }
    }
    Ok(tops)
}

/// One row of candidates to score against a tile of range blocks.
struct RowJob<'a> {
    d: &'a [Vec<f32>],
    q: &'a [f32],
    base: usize,
    len: usize,
    /// Position in R of the row's first entry, and the distance between entries.
    x0: f32,
    xstep: f32,
    ranges: &'a [Range],
    /// Texel i scores row offsets `lo[i]..=hi[i]` (its own window).
    lo: &'a [u32],
    hi: &'a [u32],
    /// Each texel's distance centre along x.
    cx: Vec<f32>,
    beta: f32,
    /// The row's distance from the centre along y.
    dy: f32,
}

/// Scores every candidate of the row for every texel of the tile into `buf` (texel i's
/// scores at `buf[i * stride..]`, +∞ outside its window) and each texel's minimum into `mins`.
fn score_row<const AVX2: bool>(
    job: &RowJob<'_>,
    nplanes: usize,
    buf: &mut [f32],
    stride: usize,
    mins: &mut [f32; TILE],
) {
    let t = job.ranges.len();
    let beta = job.beta != 0.0;
    macro_rules! dispatch {
        ($np:literal) => {
            match (t, beta) {
                (TILE, false) => score_row_n::<AVX2, $np, TILE, false>(job, buf, stride, mins),
                (TILE, true) => score_row_n::<AVX2, $np, TILE, true>(job, buf, stride, mins),
                (_, false) => score_row_n::<AVX2, $np, 1, false>(job, buf, stride, mins),
                (_, true) => score_row_n::<AVX2, $np, 1, true>(job, buf, stride, mins),
            }
        };
    }
    match nplanes {
        3 => dispatch!(3),
        4 => dispatch!(4),
        9 => dispatch!(9),
        _ => dispatch!(12),
    }
}

fn score_row_n<const AVX2: bool, const NP: usize, const T: usize, const BETA: bool>(
    job: &RowJob<'_>,
    buf: &mut [f32],
    stride: usize,
    mins: &mut [f32; TILE],
) {
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        // SAFETY: `AVX2` is true only where the encoding's `Isa` is `Fma`, which
        // `Isa::detect` or `Isa::checked` found available (AVX2, FMA, BMI1/2) on this CPU;
        // the arithmetic is the same as the portable path.
        unsafe { score_row_avx2::<NP, T, BETA>(job, buf, stride, mins) };
        return;
    }
    score_row_kernel::<NP, T, BETA>(job, buf, stride, mins);
}

/// The AVX2 form of [`score_row_kernel`]: the same operations in the same order on eight
/// lanes (no fused multiply–add), so both give bit-identical scores.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn score_row_avx2<const NP: usize, const T: usize, const BETA: bool>(
    job: &RowJob<'_>,
    buf: &mut [f32],
    stride: usize,
    mins: &mut [f32; TILE],
) {
    use std::arch::x86_64::*;
    let d: [&[f32]; NP] = std::array::from_fn(|p| &job.d[p][job.base..job.base + job.len]);
    let w: [[__m256; NP]; T] =
        std::array::from_fn(|i| std::array::from_fn(|p| _mm256_set1_ps(job.ranges[i].w[p])));
    let cxs: [__m256; T] = std::array::from_fn(|i| _mm256_set1_ps(job.cx[i]));
    let lo_m1: [__m256i; T] = std::array::from_fn(|i| _mm256_set1_epi32(job.lo[i] as i32 - 1));
    let hi_p1: [__m256i; T] = std::array::from_fn(|i| _mm256_set1_epi32(job.hi[i] as i32 + 1));
    let inner_lo = job.lo[..T].iter().copied().max().unwrap_or(0) as usize;
    let inner_hi = job.hi[..T].iter().copied().min().unwrap_or(0) as usize;
    let two = _mm256_set1_ps(2.0);
    let inf = _mm256_set1_ps(f32::INFINITY);
    let sign = _mm256_set1_ps(-0.0);
    let beta = _mm256_set1_ps(job.beta);
    let dyv = _mm256_set1_ps(job.dy);
    let x0 = _mm256_set1_ps(job.x0);
    let xstep = _mm256_set1_ps(job.xstep);
    let iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let mut mn = [inf; T];
    let chunks = job.len / LANES;
    for k in 0..chunks {
        let b = k * LANES;
        let dv: [__m256; NP] = std::array::from_fn(|p| {
            let s: &[f32; LANES] = d[p][b..b + LANES].try_into().expect("chunk of LANES");
            // SAFETY: `s` is eight readable f32s; unaligned loads are allowed.
            unsafe { _mm256_loadu_ps(s.as_ptr()) }
        });
        let qs: &[f32; LANES] = job.q[b..b + LANES].try_into().expect("chunk of LANES");
        // SAFETY: as above.
        let qv = unsafe { _mm256_loadu_ps(qs.as_ptr()) };
        let jv = _mm256_add_epi32(_mm256_set1_epi32(b as i32), iota);
        let x = _mm256_add_ps(x0, _mm256_mul_ps(xstep, _mm256_cvtepi32_ps(jv)));
        let interior = b >= inner_lo && b + LANES - 1 <= inner_hi;
        for i in 0..T {
            let mut dot = _mm256_mul_ps(w[i][0], dv[0]);
            for p in 1..NP {
                dot = _mm256_add_ps(dot, _mm256_mul_ps(w[i][p], dv[p]));
            }
            let mut sc = _mm256_sub_ps(qv, _mm256_mul_ps(two, dot));
            if BETA {
                let ax = _mm256_andnot_ps(sign, _mm256_sub_ps(x, cxs[i]));
                sc = _mm256_add_ps(sc, _mm256_mul_ps(beta, _mm256_add_ps(ax, dyv)));
            }
            if !interior {
                let ok = _mm256_and_si256(
                    _mm256_cmpgt_epi32(jv, lo_m1[i]),
                    _mm256_cmpgt_epi32(hi_p1[i], jv),
                );
                sc = _mm256_blendv_ps(inf, sc, _mm256_castsi256_ps(ok));
            }
            let out: &mut [f32; LANES] = (&mut buf[i * stride + b..i * stride + b + LANES])
                .try_into()
                .expect("chunk of LANES");
            // SAFETY: `out` is eight writable f32s; unaligned stores are allowed.
            unsafe { _mm256_storeu_ps(out.as_mut_ptr(), sc) };
            mn[i] = _mm256_min_ps(sc, mn[i]);
        }
    }
    let mut rest = [f32::INFINITY; TILE];
    tail_scores::<NP, T, BETA>(job, &d, chunks * LANES, buf, stride, &mut rest);
    for i in 0..T {
        let mut lanes = [0.0f32; LANES];
        // SAFETY: `lanes` is eight writable f32s.
        unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), mn[i]) };
        mins[i] = lanes
            .iter()
            .fold(rest[i], |a, &b| if b < a { b } else { a });
    }
}

/// Scores of the row entries `from..` (fewer than a chunk), one at a time.
#[inline(always)]
fn tail_scores<const NP: usize, const T: usize, const BETA: bool>(
    job: &RowJob<'_>,
    d: &[&[f32]; NP],
    from: usize,
    buf: &mut [f32],
    stride: usize,
    mins: &mut [f32; TILE],
) {
    for j in from..job.len {
        for i in 0..T {
            let w = &job.ranges[i].w;
            let mut dot = w[0] * d[0][j];
            for (wp, dp) in w[1..NP].iter().zip(&d[1..]) {
                dot += wp * dp[j];
            }
            let mut sc = job.q[j] - 2.0 * dot;
            if BETA {
                let x = job.x0 + job.xstep * j as f32;
                sc += job.beta * ((x - job.cx[i]).abs() + job.dy);
            }
            if !(j as u32 >= job.lo[i] && j as u32 <= job.hi[i]) {
                sc = f32::INFINITY;
            }
            buf[i * stride + j] = sc;
            if sc < mins[i] {
                mins[i] = sc;
            }
        }
    }
}

/// score = ‖d‖² − 2 Σ w·d (+ β·distance), +∞ outside the texel's window: the portable path
/// (and the reference for the AVX2 one).
fn score_row_kernel<const NP: usize, const T: usize, const BETA: bool>(
    job: &RowJob<'_>,
    buf: &mut [f32],
    stride: usize,
    mins: &mut [f32; TILE],
) {
    let d: [&[f32]; NP] = std::array::from_fn(|p| &job.d[p][job.base..job.base + job.len]);
    *mins = [f32::INFINITY; TILE];
    tail_scores::<NP, T, BETA>(job, &d, 0, buf, stride, mins);
}

/// Minimum of at most eight scores.
fn chunk_min(c: &[f32]) -> f32 {
    c.iter()
        .fold(f32::INFINITY, |a, &b| if b < a { b } else { a })
}

/// Turns a texel's candidate set into coordinates, offsets (Eq. 4) and exact collage errors.
fn finish(
    s: &Texture,
    r: &Texture,
    cfg: &EncoderConfig,
    cx: usize,
    cy: usize,
    top: TopK,
    scored: u64,
) -> TexelResult {
    let (wr, nc) = (r.width(), r.channels());
    let norm = range_block(s, cfg, cx, cy).norm;
    let items = top.finish();
    let n = items.len();
    let mut res = TexelResult {
        coords: Vec::with_capacity(n),
        offsets: Vec::with_capacity(n * nc),
        sse: Vec::with_capacity(n),
        scores: Vec::with_capacity(n),
        scored,
    };
    for &(score, _, k) in &items {
        let (kx, ky) = (k as usize % wr, k as usize / wr);
        res.coords.push(k);
        let mut sse = 0.0f32;
        for c in 0..nc {
            let rv = block(s, 2 * cx, 2 * cy, c);
            let dv = block(r, kx, ky, c);
            let o = 0.25 * (rv[0] + rv[1] + rv[2] + rv[3]) - 0.25 * (dv[0] + dv[1] + dv[2] + dv[3]);
            res.offsets.push(o);
            for j in 0..4 {
                let e = rv[j] - dv[j] - o;
                sse += e * e;
            }
        }
        res.sse.push(sse);
        // The kernel's score leaves out ‖r‖² (or ‖r̃‖²), the same for every candidate.
        res.scores.push(score + norm);
    }
    res
}
