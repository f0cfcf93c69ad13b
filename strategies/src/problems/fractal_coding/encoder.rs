//! The encoder: template matching of every 2×2 range block of the source against the 2×2
//! blocks of the reduced texture R in a search set around the domain texel.
//!
//! For a texel c of R with range block r (the source's 2×2 block at 2c, per channel) and a
//! candidate block d of R (top-left texel (x, y)), the matching error is one of
//! - [`Matching::Raw`], the paper's Eq. 3: E = ‖r − d‖², the offset computed afterwards;
//! - [`Matching::MeanRemoved`]: E = ‖r̃ − d̃‖², the SSE left after the best constant offset
//!   (r̃, d̃ the mean-removed blocks).
//!
//! Either way the offset is O = r̄ − d̄ (Eq. 4). The search minimises the score
//! E + β·(|x − x₀| + |y − y₀|), where (x₀, y₀) is c ([`DistanceCentre::Domain`]) or 2c
//! ([`DistanceCentre::Range`], Eq. 12 as printed); β = 0 is the plain encoder of Eq. 2. The
//! search set ([`SearchGrid`]) is every block within ±`window` texels of c, or only the blocks
//! at even indices (the paper's §IV), whose coordinates the packed format stores as half the
//! relative coordinate in [−125, 126]. The encoder keeps, for the refinement, the candidate set
//! Ω = {score < best + ΔE_max} (Eq. 13; the best always), best first, optionally capped.
//! Ties are broken by the distance term's Manhattan distance, then by the position in R.
//!
//! ## Speed
//! - The candidate blocks of each lattice of positions the grids use are precomputed in
//!   structure-of-arrays planes: the four raw values per channel and ‖d‖² (raw), or three
//!   mean-removed values per channel (d̃₃ = −d̃₀ − d̃₁ − d̃₂) and ‖d̃‖² (mean-removed). Scoring a
//!   candidate is then ‖d‖² − 2 w·d: 3 or 4 multiply–adds per channel.
//! - Texels are searched in tiles of four texels of a row that share a lattice: the tile shares
//!   one pass over the candidate planes (one load, four dot products), in chunks of eight lanes
//!   that the compiler vectorises (AVX2 when the CPU has it, selected at run time; the
//!   arithmetic is the same on every path, so the result does not depend on the CPU).
//! - A row of candidate scores is reduced to its minimum first; only rows whose minimum can
//!   enter the candidate set are scanned (exact: no candidate is skipped that could qualify).
//! - Rows of texels run in parallel with rayon; each texel's result depends only on its own
//!   search, so the code does not depend on the thread count.
//!
//! For 8-bit sources every quantity of the raw matching is an integer below 2²⁴, so its scores
//! are exact in `f32` and the encoder equals a brute-force search bit for bit (tested).

use std::cmp::Ordering;
use std::sync::atomic::{AtomicU64, Ordering as AtomicOrdering};
use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::problems::fractal_coding::code::FractalCode;
use crate::problems::fractal_coding::texture::Texture;

/// Most candidates the encoder keeps in all (about 1 GB for grey textures, 2 GB for RGB):
/// beyond this it refuses, rather than exhausting memory on a large uncapped Ω.
pub const MAX_TOTAL_CANDIDATES: u64 = 1 << 26;

/// Smallest half relative coordinate the even grids (and the paper's packed format) allow.
pub const HALF_MIN: i32 = -125;
/// Largest half relative coordinate the even grids (and the paper's packed format) allow.
pub const HALF_MAX: i32 = 126;

/// Implements `name`, `ALL`, `Display` and `FromStr` for a settings enum.
macro_rules! named_enum {
    ($ty:ident, $param:literal, $($variant:ident => $name:literal),+ $(,)?) => {
        impl $ty {
            /// Every value, in the order of the documentation.
            pub const ALL: &'static [$ty] = &[$($ty::$variant),+];

            /// The name used on the command line, in configs and in tables.
            pub fn name(self) -> &'static str {
                match self {
                    $($ty::$variant => $name),+
                }
            }
        }

        impl ::std::fmt::Display for $ty {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.write_str(self.name())
            }
        }

        impl ::std::str::FromStr for $ty {
            type Err = $crate::error::Error;

            fn from_str(s: &str) -> $crate::error::Result<Self> {
                $ty::ALL.iter().copied().find(|v| v.name() == s).ok_or_else(|| {
                    let names: Vec<&str> = $ty::ALL.iter().map(|v| v.name()).collect();
                    $crate::error::Error::param(
                        $param,
                        format!("unknown value `{s}`; use one of {}", names.join(", ")),
                    )
                })
            }
        }
    };
}
pub(crate) use named_enum;

/// How a candidate block is compared with the range block.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Matching {
    /// The paper's Eq. 3: the raw SSE ‖r − d‖²; the offset is computed afterwards (Eq. 4), so
    /// the match must already have about the right brightness.
    Raw,
    /// The SSE after removing the best constant offset, ‖r̃ − d̃‖²: any brightness matches.
    MeanRemoved,
}
named_enum!(Matching, "matching", Raw => "raw", MeanRemoved => "mean-removed");

/// Which blocks of R are candidates for a texel c.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SearchGrid {
    /// Every block whose top-left texel is within ±`window` of c.
    All,
    /// The paper's §IV: blocks at even indices (x and y even), with half the relative
    /// coordinate, x/2 − ⌊c_x/2⌋, in [−125, 126] (and within ±`window` of c).
    Even,
    /// The other reading of §IV: blocks at an even offset from c (x − c_x even), with
    /// (x − c_x)/2 in [−125, 126] (and within ±`window` of c).
    EvenOffset,
}
named_enum!(SearchGrid, "grid", All => "all", Even => "even", EvenOffset => "even-offset");

impl SearchGrid {
    /// Distance between neighbouring candidates along an axis.
    pub fn stride(self) -> usize {
        match self {
            SearchGrid::All => 1,
            SearchGrid::Even | SearchGrid::EvenOffset => 2,
        }
    }

    /// The base b(c) of the half relative coordinate s = (x − b(c)) / 2 along one axis:
    /// 2⌊c/2⌋ for [`SearchGrid::Even`], c for [`SearchGrid::EvenOffset`]; `None` for
    /// [`SearchGrid::All`], whose offsets need not be even.
    pub fn half_base(self, c: usize) -> Option<usize> {
        match self {
            SearchGrid::All => None,
            SearchGrid::Even => Some(c & !1),
            SearchGrid::EvenOffset => Some(c),
        }
    }

    /// The parity class (x mod 2, y mod 2) of texel c's candidates, for the even grids.
    fn class(self, cx: usize, cy: usize) -> (usize, usize) {
        match self {
            SearchGrid::All | SearchGrid::Even => (0, 0),
            SearchGrid::EvenOffset => (cx & 1, cy & 1),
        }
    }
}

/// How the reduced texture R is made from the source.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Reduction {
    /// The 2×2 box filter (the first mipmap level): R(c) is the mean of the range block at 2c.
    Box,
    /// OpenCV's `pyrDown` (5×5 binomial filter), for comparison: R(c) then also depends on the
    /// range block's neighbours.
    Binomial,
}
named_enum!(Reduction, "reduction", Box => "box", Binomial => "binomial");

/// The point the proximity term β·(|x − x₀| + |y − y₀|) measures distance from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DistanceCentre {
    /// The domain texel: (x₀, y₀) = c, so nearby blocks of R are preferred.
    Domain,
    /// The paper's Eq. 12 as printed, |x − 2c_x| + |y − 2c_y|: the range block's position in
    /// the source, compared with a position in R.
    Range,
}
named_enum!(DistanceCentre, "distance", Domain => "domain", Range => "range");

impl DistanceCentre {
    /// The multiple of c the distance is measured from.
    pub fn scale(self) -> usize {
        match self {
            DistanceCentre::Domain => 1,
            DistanceCentre::Range => 2,
        }
    }
}

/// Encoder settings. The defaults are the plain encoder (β = 0, one candidate) of the
/// default preset; see [`Preset`](crate::problems::fractal_coding::preset::Preset) for both presets.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EncoderConfig {
    /// How R is made (both presets: the box filter).
    pub reduction: Reduction,
    /// Half-width of the search window in texels of R (the paper: 255; the sign–magnitude
    /// packed format holds at most 255). At least 1 (2 for the even grids).
    pub window: u32,
    /// Matching criterion.
    pub matching: Matching,
    /// Search set.
    pub grid: SearchGrid,
    /// Weight β of the proximity term, in squared grey levels per texel of distance; 0
    /// disables it.
    pub beta: f32,
    /// Where the proximity term measures distance from.
    pub distance: DistanceCentre,
    /// ΔE_max: keep the candidates whose score is below the best's plus this (squared grey
    /// levels); 0 keeps the best only.
    pub delta_e_max: f32,
    /// At most this many candidates per texel (the best first); `None` keeps all of Ω.
    pub max_candidates: Option<usize>,
}

impl Default for EncoderConfig {
    fn default() -> Self {
        EncoderConfig {
            reduction: Reduction::Box,
            window: 255,
            matching: Matching::MeanRemoved,
            grid: SearchGrid::All,
            beta: 0.0,
            distance: DistanceCentre::Domain,
            delta_e_max: 0.0,
            max_candidates: Some(1),
        }
    }
}

impl EncoderConfig {
    /// Refuses values outside their ranges, saying what to change.
    pub fn validate(&self) -> Result<()> {
        let min_window = if self.grid == SearchGrid::All { 1 } else { 2 };
        if self.window < min_window {
            return Err(Error::param(
                "window",
                format!(
                    "must be at least {min_window} texel(s) for grid `{}`, got {} (the paper uses 255)",
                    self.grid, self.window
                ),
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
        if self.max_candidates == Some(0) {
            return Err(Error::param(
                "max_candidates",
                "must be at least 1 (or unset / `all` to keep every candidate of Ω)",
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

    /// Candidate `k` of texel `c`: (block coordinate in R as a row-major index, offsets,
    /// collage SSE after the offset, score E + β·distance).
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
    /// Mean collage error of the code: SSE per range block after the offset (squared grey
    /// levels).
    pub mean_sse: f64,
    /// Mean number of candidates kept per texel.
    pub mean_candidates: f64,
    /// Largest number of candidates kept for one texel.
    pub most_candidates: usize,
}

/// Encodes a texture with even sides of at least 4 texels (6 for the even-offset grid): R by
/// a rounded 2×2 box filter (see [`Texture::reduce`]; or [`Texture::reduce_binomial`]), then
/// the search of the module docs.
pub fn encode(source: &Texture, cfg: &EncoderConfig) -> Result<Encoding> {
    cfg.validate()?;
    let (w, h) = (source.width(), source.height());
    if !w.is_multiple_of(2) || !h.is_multiple_of(2) || w < 4 || h < 4 {
        return Err(Error::InvalidInput(format!(
            "fractal coding needs even sides of at least 4 texels (R is half size and must hold a \
             2×2 block), got {w}×{h}; crop or pad the texture"
        )));
    }
    if cfg.grid == SearchGrid::EvenOffset && (w < 6 || h < 6) {
        return Err(Error::InvalidInput(format!(
            "the even-offset grid needs sides of at least 6 texels (every texel of R needs a \
             block at an even offset), got {w}×{h}"
        )));
    }
    let t0 = Instant::now();
    let reduced = match cfg.reduction {
        Reduction::Box => source.reduce()?,
        Reduction::Binomial => source.reduce_binomial()?,
    };
    let planes = Planes::new(&reduced, cfg);
    let hr = reduced.height();
    let kept = AtomicU64::new(0);
    let rows: Vec<Vec<TexelResult>> = (0..hr)
        .into_par_iter()
        .map(|cy| search_row(source, &reduced, &planes, cfg, cy, &kept))
        .collect::<Result<_>>()?;

    let (wr, ch) = (reduced.width(), source.channels());
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
    let mut most = 0usize;
    for r in rows.into_iter().flatten() {
        coords.push(r.coords[0]);
        offsets.extend_from_slice(&r.offsets[..ch]);
        sse_sum += f64::from(r.sse[0]);
        scored += r.scored;
        most = most.max(r.coords.len());
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
            most_candidates: most,
        },
    })
}

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
struct Planes {
    stride: usize,
    lattices: Vec<Lattice>,
    /// Planes per lattice: 4 or 3 per channel.
    np: usize,
}

impl Planes {
    fn new(r: &Texture, cfg: &EncoderConfig) -> Self {
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
fn block(t: &Texture, x: usize, y: usize, c: usize) -> [f32; 4] {
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
struct TexelResult {
    coords: Vec<u32>,
    offsets: Vec<f32>,
    sse: Vec<f32>,
    scores: Vec<f32>,
    scored: u64,
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
fn search_row(
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
            let tops = search_tile(s, planes, cfg, &tile, cy, &mut buf)?;
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
fn search_tile(
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
        score_row(&job, planes.np, buf, stride, &mut mins);
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
    match nplanes {
        3 => dispatch!(3),
        4 => dispatch!(4),
        9 => dispatch!(9),
        _ => dispatch!(12),
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The search written plainly in f64, for every grid, criterion and distance centre: each
    /// texel's candidate set, best first, as (index in R, score).
    fn brute(s: &Texture, cfg: &EncoderConfig) -> Vec<Vec<(u32, f64)>> {
        let r = s.reduce().unwrap();
        let (wr, hr, nc) = (r.width(), r.height(), r.channels());
        let win = cfg.window as i64;
        let ok = |c: usize, x: usize| -> bool {
            let d = x as i64 - c as i64;
            if d.abs() > win {
                return false;
            }
            let base = match cfg.grid {
                SearchGrid::All => return true,
                SearchGrid::Even if !x.is_multiple_of(2) => return false,
                SearchGrid::Even => 2 * (c as i64 / 2),
                SearchGrid::EvenOffset if d % 2 != 0 => return false,
                SearchGrid::EvenOffset => c as i64,
            };
            let h = (x as i64 - base) / 2;
            (i64::from(HALF_MIN)..=i64::from(HALF_MAX)).contains(&h)
        };
        let k = cfg.distance.scale();
        let mut out = Vec::new();
        for cy in 0..hr {
            for cx in 0..wr {
                let mut all: Vec<(f64, u32, u32)> = Vec::new();
                for ky in 0..hr - 1 {
                    for kx in 0..wr - 1 {
                        if !ok(cx, kx) || !ok(cy, ky) {
                            continue;
                        }
                        let mut e = 0.0f64;
                        for c in 0..nc {
                            let rv = block(s, 2 * cx, 2 * cy, c).map(f64::from);
                            let dv = block(&r, kx, ky, c).map(f64::from);
                            let o = match cfg.matching {
                                Matching::Raw => 0.0,
                                Matching::MeanRemoved => {
                                    (rv.iter().sum::<f64>() - dv.iter().sum::<f64>()) / 4.0
                                }
                            };
                            e += (0..4).map(|j| (rv[j] - dv[j] - o).powi(2)).sum::<f64>();
                        }
                        let man = (kx.abs_diff(k * cx) + ky.abs_diff(k * cy)) as u32;
                        all.push((
                            e + f64::from(cfg.beta) * f64::from(man),
                            man,
                            (ky * wr + kx) as u32,
                        ));
                    }
                }
                all.sort_by(|a, b| a.0.total_cmp(&b.0).then((a.1, a.2).cmp(&(b.1, b.2))));
                let best = all[0].0;
                let mut set: Vec<(u32, f64)> = all
                    .iter()
                    .enumerate()
                    .filter(|(i, a)| *i == 0 || a.0 < best + f64::from(cfg.delta_e_max))
                    .map(|(_, a)| (a.2, a.0))
                    .collect();
                set.truncate(cfg.max_candidates.unwrap_or(usize::MAX));
                out.push(set);
            }
        }
        out
    }

    fn noise(w: usize, h: usize, ch: usize, levels: u64, seed: u64) -> Texture {
        let mut state = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let v = (0..w * h * ch)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 33) % levels * (256 / levels)) as f32
            })
            .collect();
        Texture::new(w, h, ch, v).unwrap()
    }

    fn cfg(
        matching: Matching,
        grid: SearchGrid,
        distance: DistanceCentre,
        window: u32,
        beta: f32,
        delta: f32,
        cap: Option<usize>,
    ) -> EncoderConfig {
        EncoderConfig {
            reduction: Reduction::Box,
            window,
            matching,
            grid,
            beta,
            distance,
            delta_e_max: delta,
            max_candidates: cap,
        }
    }

    #[test]
    fn raw_matching_equals_the_exhaustive_search_exactly() {
        // Raw scores of 8-bit textures are exact integers in f32: the candidate sets must be
        // the same, in the same order, with the same scores. Coarse grey levels make ties.
        use DistanceCentre::*;
        use SearchGrid::*;
        let cases = [
            (38, 30, 1, 255, All, Domain, 0.0, 0.0, Some(1)),
            (38, 30, 3, 3, All, Range, 1.0, 100.0, None),
            (40, 28, 1, 5, Even, Range, 1.0, 100.0, None),
            // Grey levels are multiples of 32, raw SSEs of 1024: candidates at exactly
            // E* + ΔE_max are frequent and must be left out (Eq. 13 is strict).
            (40, 28, 1, 255, Even, Range, 0.0, 2048.0, None),
            (40, 28, 3, 255, Even, Domain, 0.5, 3000.0, Some(7)),
            (36, 30, 1, 4, EvenOffset, Range, 1.0, 2000.0, None),
            (36, 30, 3, 255, EvenOffset, Domain, 0.0, 0.0, Some(1)),
            // R is 260 wide: the half coordinate's [−125, 126] limit and the ±255 window bind.
            (520, 8, 1, 255, Even, Range, 1.0, 100.0, None),
            (520, 8, 1, 255, EvenOffset, Domain, 0.0, 500.0, Some(40)),
            (520, 8, 1, 255, All, Domain, 0.0, 0.0, Some(1)),
        ];
        for (w, h, ch, window, grid, dist, beta, delta, cap) in cases {
            let levels = if ch == 1 { 8 } else { 4 };
            let s = noise(w, h, ch, levels, (w + 7 * ch) as u64);
            let cfg = cfg(Matching::Raw, grid, dist, window, beta, delta, cap);
            let enc = encode(&s, &cfg).unwrap();
            let want = brute(&s, &cfg);
            for (c, want) in want.iter().enumerate() {
                let got: Vec<(u32, f64)> = (0..enc.candidates.count(c))
                    .map(|k| {
                        let (i, _, _, sc) = enc.candidates.get(c, k);
                        (i, f64::from(sc))
                    })
                    .collect();
                assert_eq!(&got, want, "texel {c} of {w}×{h}×{ch}, {cfg:?}");
                assert_eq!(enc.code.coords()[c], want[0].0);
            }
        }
    }

    #[test]
    fn mean_removed_matching_finds_the_exhaustive_minimum() {
        use DistanceCentre::*;
        use SearchGrid::*;
        for (ch, grid, dist, beta, window) in [
            (1, All, Domain, 0.0, 255),
            (3, All, Domain, 0.0, 3),
            (1, All, Range, 2.0, 5),
            (3, Even, Domain, 0.5, 255),
            (1, EvenOffset, Range, 1.0, 7),
        ] {
            let s = noise(38, 30, ch, 256, 7 + ch as u64);
            let cfg = cfg(
                Matching::MeanRemoved,
                grid,
                dist,
                window,
                beta,
                0.0,
                Some(1),
            );
            let enc = encode(&s, &cfg).unwrap();
            for (c, want) in brute(&s, &cfg).iter().enumerate() {
                let (_, _, sse, got) = enc.candidates.get(c, 0);
                let score = want[0].1 as f32;
                // Same minimum score (the position may differ only on near-ties).
                assert!(
                    (got - score).abs() <= 1e-2 * (1.0 + score.abs()),
                    "texel {c}: fast {got} vs exhaustive {score} ({cfg:?})"
                );
                assert!(sse >= 0.0);
            }
        }
    }

    #[test]
    fn candidate_sets_respect_delta_and_cap() {
        let s = noise(24, 24, 1, 256, 3);
        let cfg = cfg(
            Matching::MeanRemoved,
            SearchGrid::All,
            DistanceCentre::Domain,
            6,
            1.0,
            400.0,
            Some(5),
        );
        let enc = encode(&s, &cfg).unwrap();
        let c = &enc.candidates;
        for t in 0..c.texels() {
            let n = c.count(t);
            assert!((1..=5).contains(&n));
            let best = c.get(t, 0).3;
            for k in 0..n {
                let (coord, _, _, score) = c.get(t, k);
                assert!(k == 0 || (score < best + 400.0 && score >= best));
                let (x, y) = (t % 12, t / 12);
                let (kx, ky) = (coord as usize % 12, coord as usize / 12);
                assert!(kx.abs_diff(x) <= 6 && ky.abs_diff(y) <= 6);
            }
        }
    }

    #[test]
    fn bad_sizes_and_parameters_are_refused() {
        let t = |w, h| noise(w, h, 1, 256, 1);
        assert!(encode(&t(5, 8), &EncoderConfig::default()).is_err());
        assert!(encode(&t(2, 8), &EncoderConfig::default()).is_err());
        let bad = |f: fn(&mut EncoderConfig)| {
            let mut c = EncoderConfig::default();
            f(&mut c);
            encode(&t(8, 8), &c).unwrap_err().to_string()
        };
        assert!(bad(|c| c.window = 0).contains("window"));
        assert!(
            bad(|c| {
                c.grid = SearchGrid::Even;
                c.window = 1
            })
            .contains("at least 2")
        );
        assert!(bad(|c| c.max_candidates = Some(0)).contains("max_candidates"));
        assert!(bad(|c| c.beta = f32::NAN).contains("beta"));
        assert!(bad(|c| c.delta_e_max = -1.0).contains("delta_e_max"));
        let offset = EncoderConfig {
            grid: SearchGrid::EvenOffset,
            ..EncoderConfig::default()
        };
        assert!(encode(&t(4, 8), &offset).is_err());
        assert!(encode(&t(6, 6), &offset).is_ok());
        assert_eq!("even".parse::<SearchGrid>().unwrap(), SearchGrid::Even);
        let e = "odd".parse::<SearchGrid>().unwrap_err().to_string();
        assert!(e.contains("all, even, even-offset"), "{e}");
    }
}
