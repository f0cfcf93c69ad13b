//! The encoder: template matching of every 2×2 range block of the source against the 2×2
//! blocks of the reduced texture R inside a ±`window` search window.
//!
//! For a texel c of R with range block r (the source's 2×2 block at 2c, per channel), the
//! error of a candidate block d of R with the best offset is the sum of squared errors of the
//! mean-removed blocks, E = ‖r̃‖² + ‖d̃‖² − 2 r̃·d̃, and the offset is O = r̄ − d̄. The search
//! minimises the score E + β·(|Δx| + |Δy|) (Δ = candidate − c; β = 0 is plain fractal coding)
//! and keeps up to `max_candidates` candidates whose score is within `delta_e_max` of the
//! best, for the refinement.
//!
//! ## Speed
//! - ‖d̃‖² and three mean-removed values per channel are precomputed per candidate position in
//!   structure-of-arrays planes (d̃₃ = −d̃₀ − d̃₁ − d̃₂, so three planes carry a channel);
//!   scoring a candidate is then 3 multiply–adds per channel.
//! - Texels are searched in tiles of four neighbours of a row: the tile shares one pass over
//!   the candidate planes (one load, four dot products), in chunks of eight lanes that the
//!   compiler vectorises (AVX2 when the CPU has it, selected at run time; the arithmetic is
//!   the same on every path, so the result does not depend on the CPU).
//! - A row of candidate scores is reduced to its minimum first; only rows whose minimum can
//!   enter the candidate list are scanned (exact: no candidate is skipped that could qualify).
//! - Rows of texels run in parallel with rayon; each texel's result depends only on its own
//!   search, so the code does not depend on the thread count.

use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::fractal_coding::code::FractalCode;
use crate::fractal_coding::texture::Texture;

/// Encoder settings. The defaults are plain fractal coding in the paper's ±255 window.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EncoderConfig {
    /// Half-width of the search window in texels of R (the paper: 255, the range of the packed
    /// 8-bit relative coordinates). Must be at least 1.
    pub window: u32,
    /// Weight β of the spatial-proximity term β·(|Δx| + |Δy|), in squared grey levels per
    /// texel of distance; 0 disables it.
    pub beta: f32,
    /// Keep the candidates whose score is within this of the best (squared grey levels).
    pub delta_e_max: f32,
    /// At most this many candidates per texel (the best first); 1 keeps only the best.
    pub max_candidates: usize,
}

impl Default for EncoderConfig {
    fn default() -> Self {
        EncoderConfig {
            window: 255,
            beta: 0.0,
            delta_e_max: 0.0,
            max_candidates: 1,
        }
    }
}

impl EncoderConfig {
    /// Refuses values outside their ranges, saying what to change.
    pub fn validate(&self) -> Result<()> {
        if self.window == 0 {
            return Err(Error::param(
                "window",
                "must be at least 1 texel (the paper uses 255)",
            ));
        }
        if !(self.beta.is_finite() && self.beta >= 0.0) {
            return Err(Error::param(
                "beta",
                format!("must be a finite number ≥ 0, got {}", self.beta),
            ));
        }
        if !(self.delta_e_max.is_finite() && self.delta_e_max >= 0.0) {
            return Err(Error::param(
                "delta_e_max",
                format!("must be a finite number ≥ 0, got {}", self.delta_e_max),
            ));
        }
        if self.max_candidates == 0 || self.max_candidates > 256 {
            return Err(Error::param(
                "max_candidates",
                format!("must be between 1 and 256, got {}", self.max_candidates),
            ));
        }
        Ok(())
    }
}

/// The candidate virtual ranges of every texel, best first (compressed rows: texel c owns
/// entries `start[c]..start[c + 1]`).
#[derive(Clone, Debug, PartialEq)]
pub struct Candidates {
    /// Size of the reduced texture the coordinates index.
    width: usize,
    height: usize,
    channels: usize,
    start: Vec<u32>,
    coords: Vec<u32>,
    offsets: Vec<f32>,
    sse: Vec<f32>,
    scores: Vec<f32>,
}

impl Candidates {
    /// (width, height, channels) of the reduced texture the candidates belong to.
    pub fn shape(&self) -> (usize, usize, usize) {
        (self.width, self.height, self.channels)
    }

    /// Number of texels.
    pub fn texels(&self) -> usize {
        self.start.len() - 1
    }

    /// Number of candidates of texel `c`.
    pub fn count(&self, c: usize) -> usize {
        (self.start[c + 1] - self.start[c]) as usize
    }

    /// Total number of candidates.
    pub fn total(&self) -> usize {
        self.coords.len()
    }

    /// Candidate `k` of texel `c`: (block coordinate in R, offsets, SSE, score).
    pub fn get(&self, c: usize, k: usize) -> (u32, &[f32], f32, f32) {
        let i = self.start[c] as usize + k;
        let ch = self.channels;
        (
            self.coords[i],
            &self.offsets[i * ch..(i + 1) * ch],
            self.sse[i],
            self.scores[i],
        )
    }
}

/// What the encoder produced.
#[derive(Clone, Debug)]
pub struct Encoding {
    /// The code made of every texel's best candidate.
    pub code: FractalCode,
    /// Every texel's candidate list (its first entry is the code's).
    pub candidates: Candidates,
    /// Summary of the run.
    pub stats: EncodeStats,
}

/// Summary of an encoder run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EncodeStats {
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Candidate blocks scored (all texels).
    pub candidates_scored: u64,
    /// Mean collage error of the code: SSE per range block (squared grey levels).
    pub mean_sse: f64,
    /// Mean number of candidates kept per texel.
    pub mean_candidates: f64,
}

/// Encodes a texture with even sides of at least 4 texels: R by a rounded 2×2 box filter
/// (see [`Texture::reduce`]), then the search described in the module docs.
pub fn encode(source: &Texture, cfg: &EncoderConfig) -> Result<Encoding> {
    cfg.validate()?;
    let (w, h) = (source.width(), source.height());
    if !w.is_multiple_of(2) || !h.is_multiple_of(2) || w < 4 || h < 4 {
        return Err(Error::InvalidInput(format!(
            "fractal coding needs even sides of at least 4 texels (R is half size and must hold a \
             2×2 block), got {w}×{h}; crop or pad the texture"
        )));
    }
    let t0 = Instant::now();
    let reduced = source.reduce()?;
    let planes = Planes::new(&reduced);
    let (wr, hr) = (reduced.width(), reduced.height());
    let rows: Vec<Vec<TexelResult>> = (0..hr)
        .into_par_iter()
        .map(|cy| search_row(source, &reduced, &planes, cfg, cy))
        .collect();

    let ch = source.channels();
    let n = wr * hr;
    let mut cand = Candidates {
        width: wr,
        height: hr,
        channels: ch,
        start: Vec::with_capacity(n + 1),
        coords: Vec::new(),
        offsets: Vec::new(),
        sse: Vec::new(),
        scores: Vec::new(),
    };
    cand.start.push(0);
    let mut coords = Vec::with_capacity(n);
    let mut offsets = Vec::with_capacity(n * ch);
    let mut sse_sum = 0.0f64;
    let mut scored = 0u64;
    for r in rows.into_iter().flatten() {
        coords.push(r.coords[0]);
        offsets.extend_from_slice(&r.offsets[..ch]);
        sse_sum += f64::from(r.sse[0]);
        scored += r.scored;
        cand.coords.extend_from_slice(&r.coords);
        cand.offsets.extend_from_slice(&r.offsets);
        cand.sse.extend_from_slice(&r.sse);
        cand.scores.extend_from_slice(&r.scores);
        cand.start.push(cand.coords.len() as u32);
    }
    let mean_candidates = cand.total() as f64 / n as f64;
    let code = FractalCode::new(reduced, coords, offsets)?;
    Ok(Encoding {
        code,
        candidates: cand,
        stats: EncodeStats {
            seconds: t0.elapsed().as_secs_f64(),
            candidates_scored: scored,
            mean_sse: sse_sum / n as f64,
            mean_candidates,
        },
    })
}

/// Candidate positions (top-left texels of R's 2×2 blocks) as structure-of-arrays planes.
struct Planes {
    /// Candidates per row (R's width − 1) and rows (R's height − 1).
    cw: usize,
    ch_rows: usize,
    /// 3 planes per channel of mean-removed values d̃₀, d̃₁, d̃₂.
    d: Vec<Vec<f32>>,
    /// ‖d̃‖² over the four texels and every channel.
    q: Vec<f32>,
}

impl Planes {
    fn new(r: &Texture) -> Self {
        let (cw, chr, nc) = (r.width() - 1, r.height() - 1, r.channels());
        let mut d = vec![vec![0.0f32; cw * chr]; 3 * nc];
        let mut q = vec![0.0f32; cw * chr];
        for y in 0..chr {
            for x in 0..cw {
                let k = y * cw + x;
                let mut qq = 0.0f32;
                for c in 0..nc {
                    let v = block(r, x, y, c);
                    let m = 0.25 * (v[0] + v[1] + v[2] + v[3]);
                    for j in 0..4 {
                        let t = v[j] - m;
                        qq += t * t;
                        if j < 3 {
                            d[3 * c + j][k] = t;
                        }
                    }
                }
                q[k] = qq;
            }
        }
        Planes {
            cw,
            ch_rows: chr,
            d,
            q,
        }
    }
}

/// The 2×2 block of channel `c` at top-left `(x, y)`, in the order (0,0), (1,0), (0,1), (1,1).
fn block(t: &Texture, x: usize, y: usize, c: usize) -> [f32; 4] {
    [
        t.get(x, y, c),
        t.get(x + 1, y, c),
        t.get(x, y + 1, c),
        t.get(x + 1, y + 1, c),
    ]
}

/// One texel's candidates, best first.
struct TexelResult {
    coords: Vec<u32>,
    offsets: Vec<f32>,
    sse: Vec<f32>,
    scores: Vec<f32>,
    scored: u64,
}

/// A texel's range block, prepared for scoring.
struct Range {
    /// Dot-product weights r̃ⱼ − r̃₃ (j < 3) per channel, flattened like the planes.
    w: [f32; 9],
}

fn range_block(s: &Texture, cx: usize, cy: usize) -> Range {
    let mut w = [0.0f32; 9];
    for c in 0..s.channels() {
        let v = block(s, 2 * cx, 2 * cy, c);
        let m = 0.25 * (v[0] + v[1] + v[2] + v[3]);
        let t3 = v[3] - m;
        for j in 0..3 {
            w[3 * c + j] = (v[j] - m) - t3;
        }
    }
    Range { w }
}

/// The best candidates of one texel, ordered by (score, distance, position).
struct TopK {
    k: usize,
    delta: f32,
    items: Vec<(f32, u32, u32)>,
}

impl TopK {
    fn new(k: usize, delta: f32) -> Self {
        TopK {
            k,
            delta,
            items: Vec::with_capacity(k + 1),
        }
    }

    /// Scores above this cannot enter the list.
    fn threshold(&self) -> f32 {
        match self.items.first() {
            None => f32::INFINITY,
            Some(&(best, _, _)) => {
                let t = best + self.delta;
                if self.items.len() == self.k {
                    t.min(self.items[self.k - 1].0)
                } else {
                    t
                }
            }
        }
    }

    /// Whether no candidate of a row can enter the list, given a lower bound of the row's
    /// (score, distance, position) keys.
    fn cannot_improve(&self, score: f32, man: u32, idx: u32) -> bool {
        let thr = self.threshold();
        if score != thr {
            return score > thr;
        }
        // A tie on the score enters only if it wins the tie-break on (distance, position).
        self.items.len() == self.k && {
            let last = self.items[self.k - 1];
            (man, idx) >= (last.1, last.2)
        }
    }

    fn push(&mut self, item: (f32, u32, u32)) {
        let key = |a: &(f32, u32, u32)| (a.0, a.1, a.2);
        let pos = self
            .items
            .partition_point(|x| key(x).partial_cmp(&key(&item)) == Some(std::cmp::Ordering::Less));
        if pos >= self.k {
            return;
        }
        self.items.insert(pos, item);
        self.items.truncate(self.k);
        let limit = self.items[0].0 + self.delta;
        while self.items.last().is_some_and(|x| x.0 > limit) {
            self.items.pop();
        }
    }
}

/// Texels searched together (one pass over the candidates scores a whole tile).
const TILE: usize = 4;
/// Lanes of the vectorised candidate loop.
const LANES: usize = 8;

fn search_row(
    s: &Texture,
    r: &Texture,
    planes: &Planes,
    cfg: &EncoderConfig,
    cy: usize,
) -> Vec<TexelResult> {
    let wr = r.width();
    let mut out = Vec::with_capacity(wr);
    let mut buf = vec![0.0f32; TILE * (planes.cw + LANES)];
    let mut cx = 0;
    while cx < wr {
        let t = if cx + TILE <= wr { TILE } else { 1 };
        let tops = search_tile(s, planes, cfg, cx, cy, t, &mut buf);
        for (i, (top, scored)) in tops.into_iter().enumerate() {
            out.push(finish(s, r, cx + i, cy, top, scored));
        }
        cx += t;
    }
    out
}

/// Searches texels `cx..cx + t` of row `cy`; returns their candidate lists and counts.
fn search_tile(
    s: &Texture,
    planes: &Planes,
    cfg: &EncoderConfig,
    cx: usize,
    cy: usize,
    t: usize,
    buf: &mut [f32],
) -> Vec<(TopK, u64)> {
    let win = cfg.window as usize;
    let (cw, chr) = (planes.cw, planes.ch_rows);
    let ky0 = cy.saturating_sub(win);
    let ky1 = (cy + win).min(chr - 1);
    let ux0 = cx.saturating_sub(win);
    let ux1 = (cx + t - 1 + win).min(cw - 1);
    let len = ux1 + 1 - ux0;
    let stride = cw + LANES;
    let ranges: Vec<Range> = (0..t).map(|i| range_block(s, cx + i, cy)).collect();
    // Each texel's own window inside the tile's union of windows, as row offsets.
    let lo: Vec<u32> = (0..t)
        .map(|i| ((cx + i).saturating_sub(win).max(ux0) - ux0) as u32)
        .collect();
    let hi: Vec<u32> = (0..t)
        .map(|i| ((cx + i + win).min(cw - 1) - ux0) as u32)
        .collect();
    let mut tops: Vec<(TopK, u64)> = (0..t)
        .map(|_| (TopK::new(cfg.max_candidates, cfg.delta_e_max), 0))
        .collect();
    let nplanes = 3 * s.channels();
    let mut mins = [f32::INFINITY; TILE];
    // Rows nearest to the texel first, so that ties (equal scores, e.g. flat blocks) are
    // settled early by distance; the result does not depend on this order.
    // (The last texel row has no candidate row of its own: R's last row starts no block.)
    let inside = move |k: &usize| (ky0..=ky1).contains(k);
    let rows = (0..=win.min(chr)).flat_map(move |d| {
        let up = cy.checked_sub(d).filter(inside);
        let down = (d > 0).then_some(cy + d).filter(inside);
        up.into_iter().chain(down)
    });
    for ky in rows {
        let base = ky * cw + ux0;
        let dy = ky.abs_diff(cy) as f32;
        let job = RowJob {
            d: &planes.d,
            q: &planes.q[base..base + len],
            base,
            len,
            x0: ux0 as f32,
            ranges: &ranges,
            lo: &lo,
            hi: &hi,
            cx: cx as f32,
            beta: cfg.beta,
            dy,
        };
        score_row(&job, nplanes, buf, stride, &mut mins);
        for (i, (top, scored)) in tops.iter_mut().enumerate() {
            let (lo, hi) = (lo[i] as usize, hi[i] as usize);
            *scored += (hi + 1 - lo) as u64;
            if top.cannot_improve(mins[i], ky.abs_diff(cy) as u32, (ky * cw + ux0 + lo) as u32) {
                continue;
            }
            // Only chunks of eight that hold a qualifying score are scanned one by one.
            let row = &buf[i * stride + lo..i * stride + hi + 1];
            for (n, chunk) in row.chunks(LANES).enumerate() {
                if chunk_min(chunk) > top.threshold() {
                    continue;
                }
                for (j, &sc) in chunk.iter().enumerate() {
                    if sc <= top.threshold() {
                        let kx = ux0 + lo + n * LANES + j;
                        let man = (kx.abs_diff(cx + i) + ky.abs_diff(cy)) as u32;
                        top.push((sc, man, (ky * cw + kx) as u32));
                    }
                }
            }
        }
    }
    tops
}

/// One row of candidates to score against a tile of range blocks.
struct RowJob<'a> {
    d: &'a [Vec<f32>],
    q: &'a [f32],
    base: usize,
    len: usize,
    x0: f32,
    ranges: &'a [Range],
    /// Texel i scores row offsets `lo[i]..=hi[i]` (its own window).
    lo: &'a [u32],
    hi: &'a [u32],
    cx: f32,
    beta: f32,
    dy: f32,
}

/// Scores every candidate of the row for every texel of the tile into `buf` (texel i's
/// scores at `buf[i * stride..]`, +∞ outside its window) and each texel's minimum into `mins`.
fn score_row(
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
                (TILE, false) => score_row_n::<$np, TILE, false>(job, buf, stride, mins),
                (TILE, true) => score_row_n::<$np, TILE, true>(job, buf, stride, mins),
                (_, false) => score_row_n::<$np, 1, false>(job, buf, stride, mins),
                (_, true) => score_row_n::<$np, 1, true>(job, buf, stride, mins),
            }
        };
    }
    if nplanes == 3 {
        dispatch!(3)
    } else {
        dispatch!(9)
    }
}

fn score_row_n<const NP: usize, const T: usize, const BETA: bool>(
    job: &RowJob<'_>,
    buf: &mut [f32],
    stride: usize,
    mins: &mut [f32; TILE],
) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above), the only requirement of
            // the target-feature function; the arithmetic is the same as the portable path.
            unsafe { score_row_avx2::<NP, T, BETA>(job, buf, stride, mins) };
            return;
        }
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
    let cxs: [__m256; T] = std::array::from_fn(|i| _mm256_set1_ps(job.cx + i as f32));
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
        let x = _mm256_add_ps(x0, _mm256_cvtepi32_ps(jv));
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
                let x = job.x0 + j as f32;
                sc += job.beta * ((x - (job.cx + i as f32)).abs() + job.dy);
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

/// score = ‖d̃‖² − 2 Σ w·d̃ (+ β·(|Δx| + |Δy|)), +∞ outside the texel's window: the
/// portable path (and the reference for the AVX2 one).
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

/// Turns a texel's candidate list into coordinates, offsets and exact errors.
fn finish(s: &Texture, r: &Texture, cx: usize, cy: usize, top: TopK, scored: u64) -> TexelResult {
    let (wr, cw, nc) = (r.width(), r.width() - 1, r.channels());
    let n = top.items.len();
    let mut res = TexelResult {
        coords: Vec::with_capacity(n),
        offsets: Vec::with_capacity(n * nc),
        sse: Vec::with_capacity(n),
        scores: Vec::with_capacity(n),
        scored,
    };
    // The kernel's score leaves out ‖r̃‖², the same for every candidate: add it back.
    let rnorm: f32 = (0..nc)
        .map(|c| {
            let v = block(s, 2 * cx, 2 * cy, c);
            let m = 0.25 * (v[0] + v[1] + v[2] + v[3]);
            v.iter().map(|x| (x - m) * (x - m)).sum::<f32>()
        })
        .sum();
    for &(score, _, k) in &top.items {
        let (kx, ky) = (k as usize % cw, k as usize / cw);
        res.coords.push((ky * wr + kx) as u32);
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
        res.scores.push(score + rnorm);
    }
    res
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The exhaustive search, written plainly: the fast kernel must agree with it.
    fn brute(s: &Texture, cfg: &EncoderConfig) -> Vec<(u32, f32)> {
        let r = s.reduce().unwrap();
        let (wr, hr, nc) = (r.width(), r.height(), r.channels());
        let mut out = Vec::new();
        for cy in 0..hr {
            for cx in 0..wr {
                let mut best = (f64::INFINITY, u32::MAX, 0u32);
                for ky in 0..hr - 1 {
                    for kx in 0..wr - 1 {
                        if kx.abs_diff(cx) > cfg.window as usize
                            || ky.abs_diff(cy) > cfg.window as usize
                        {
                            continue;
                        }
                        let mut sse = 0.0f64;
                        for c in 0..nc {
                            let rv = block(s, 2 * cx, 2 * cy, c).map(f64::from);
                            let dv = block(&r, kx, ky, c).map(f64::from);
                            let o = (rv.iter().sum::<f64>() - dv.iter().sum::<f64>()) / 4.0;
                            sse += (0..4).map(|j| (rv[j] - dv[j] - o).powi(2)).sum::<f64>();
                        }
                        let man = (kx.abs_diff(cx) + ky.abs_diff(cy)) as u32;
                        let score = sse + f64::from(cfg.beta) * f64::from(man);
                        if score < best.0 - 1e-3 {
                            best = (score, man, (ky * wr + kx) as u32);
                        }
                    }
                }
                out.push((best.2, best.0 as f32));
            }
        }
        out
    }

    fn noise(w: usize, h: usize, ch: usize, seed: u64) -> Texture {
        let mut state = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let v = (0..w * h * ch)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 33) % 256) as f32
            })
            .collect();
        Texture::new(w, h, ch, v).unwrap()
    }

    #[test]
    fn fast_search_finds_the_exhaustive_minimum() {
        for (ch, beta, window) in [(1, 0.0, 255), (3, 0.0, 3), (1, 2.0, 5), (3, 0.5, 255)] {
            let s = noise(38, 30, ch, 7 + ch as u64);
            let cfg = EncoderConfig {
                window,
                beta,
                ..EncoderConfig::default()
            };
            let enc = encode(&s, &cfg).unwrap();
            let want = brute(&s, &cfg);
            for (c, &(_, score)) in want.iter().enumerate() {
                let (_, _, sse, got) = enc.candidates.get(c, 0);
                // Same minimum score (the position may differ only on exact ties).
                assert!(
                    (got - score).abs() <= 1e-2 * (1.0 + score.abs()),
                    "texel {c}: fast {got} vs exhaustive {score} (ch {ch}, β {beta}, window {window})"
                );
                assert!(sse >= 0.0);
            }
        }
    }

    #[test]
    fn candidate_lists_respect_delta_and_cap() {
        let s = noise(24, 24, 1, 3);
        let cfg = EncoderConfig {
            window: 6,
            beta: 1.0,
            delta_e_max: 400.0,
            max_candidates: 5,
        };
        let enc = encode(&s, &cfg).unwrap();
        let c = &enc.candidates;
        for t in 0..c.texels() {
            let n = c.count(t);
            assert!((1..=5).contains(&n));
            let best = c.get(t, 0).3;
            for k in 0..n {
                let (coord, _, _, score) = c.get(t, k);
                assert!(score <= best + 400.0 && score >= best);
                let (x, y) = (t % 12, t / 12);
                let (kx, ky) = (coord as usize % 12, coord as usize / 12);
                assert!(kx.abs_diff(x) <= 6 && ky.abs_diff(y) <= 6);
            }
        }
    }

    #[test]
    fn bad_sizes_and_parameters_are_refused() {
        assert!(encode(&noise(5, 8, 1, 1), &EncoderConfig::default()).is_err());
        assert!(encode(&noise(2, 8, 1, 1), &EncoderConfig::default()).is_err());
        let bad = EncoderConfig {
            window: 0,
            ..EncoderConfig::default()
        };
        assert!(encode(&noise(8, 8, 1, 1), &bad).is_err());
    }
}
