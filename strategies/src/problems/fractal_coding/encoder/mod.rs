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

use std::sync::atomic::AtomicU64;
use std::time::Instant;

use ifslab::isa::Isa;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::problems::fractal_coding::code::FractalCode;
use crate::problems::fractal_coding::texture::Texture;

mod search;
use search::{Planes, TexelResult, search_row};

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
/// the search of the module docs, on the instruction set this CPU has best.
pub fn encode(source: &Texture, cfg: &EncoderConfig) -> Result<Encoding> {
    encode_with_isa(source, cfg, Isa::detect())
}

/// [`encode`] with the search's scoring loops on instruction set `isa` (an error if this CPU
/// lacks it): the same encoding on every instruction set.
pub fn encode_with_isa(source: &Texture, cfg: &EncoderConfig, isa: Isa) -> Result<Encoding> {
    let isa = isa.checked()?;
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
    let planes = Planes::new(&reduced, cfg, isa);
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

#[cfg(test)]
mod tests {
    use super::search::block;
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

    /// The AVX2 scoring loops and the portable ones find the same candidates with the
    /// same scores (bit for bit), raw and mean-removed, with and without the distance term.
    #[test]
    #[cfg_attr(
        not(target_arch = "x86_64"),
        ignore = "the AVX2 loops exist on x86-64 only"
    )]
    fn instruction_sets_give_the_same_encoding() {
        assert!(
            Isa::Fma.is_available(),
            "this x86-64 CPU has no AVX2: the SIMD scoring cannot be checked"
        );
        use DistanceCentre::*;
        use SearchGrid::*;
        for (ch, matching, grid, beta, window) in [
            (1, Matching::Raw, All, 0.0, 255),
            (3, Matching::MeanRemoved, Even, 0.5, 7),
            (1, Matching::MeanRemoved, EvenOffset, 1.0, 255),
        ] {
            let s = noise(44, 30, ch, 256, 11 + ch as u64);
            let cfg = cfg(matching, grid, Range, window, beta, 50.0, Some(9));
            let a = encode_with_isa(&s, &cfg, Isa::Fma).unwrap();
            let b = encode_with_isa(&s, &cfg, Isa::Portable).unwrap();
            assert_eq!(a.code.coords(), b.code.coords(), "{cfg:?}");
            assert_eq!(a.code.offsets(), b.code.offsets(), "{cfg:?}");
            for c in 0..a.code.coords().len() {
                assert_eq!(a.candidates.count(c), b.candidates.count(c), "{cfg:?}");
                for k in 0..a.candidates.count(c) {
                    let (x, y) = (a.candidates.get(c, k), b.candidates.get(c, k));
                    assert_eq!(x.0, y.0, "texel {c}, {cfg:?}");
                    assert_eq!(x.3.to_bits(), y.3.to_bits(), "texel {c}, {cfg:?}");
                }
            }
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
