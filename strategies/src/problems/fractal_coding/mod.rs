//! Fractal-coding texture upsampling (Kominami & Mukai): a texture's cross-scale
//! self-similarity encoded as per-texel codes of a partitioned (local) IFS, decoded
//! recursively to any power-of-two resolution, every output texel on its own.
//!
//! The algorithm:
//! 1. **Encode** ([`encoder`]): reduce the source S to R (½ size, 2×2 box filter, whole grey
//!    levels). For every texel c of R, find the 2×2 block of R (top-left C(c), in a search set
//!    around c) that best matches S's 2×2 range block at 2c — by raw SSE as in the paper, or
//!    up to a constant — and store the mean difference, the offset O(c). (R, C, O) is the code
//!    ([`code`]).
//! 2. **Refine** ([`mod@refine`], optional): among candidates within ΔE_max of the best
//!    (scored with a β·Manhattan proximity term), choose per block, by block-coordinate
//!    descent, the one minimising the variance of the Laplacian of the synthesised texture.
//! 3. **Pack** ([`packed`]): C as 8-bit coordinates (the paper's half relative coordinates,
//!    or sign–magnitude) and O as 8-bit offsets, in PNGs.
//!
//! [`preset`] names two complete settings: `paper` (the method as the paper writes it) and
//! `ifslab` (mean-removed matching over every block, this project's variant).
//! 4. **Decode** ([`decoder`]): T_n(p) = R(c_n) + Σ_{i<n} O(c_i) with c_n = C(c_{n−1}) + Δ_n,
//!    for a 2ⁿ-times-R output; factor 1 reconstructs the source.
//!
//! [`baselines`] holds the interpolation filters compared against, and [`texture`] the
//! texture type and its PNG input/output.
//!
//! ```
//! use ifslab_strategies::problems::fractal_coding::{EncoderConfig, Texture, decode, encode};
//! let s = Texture::from_fn(16, 16, 1, |x, y, _| ((x * 7 + y * 13) % 32) as f32 * 8.0)?;
//! let enc = encode(&s, &EncoderConfig { window: 4, ..EncoderConfig::default() })?;
//! let up = decode(&enc.code, 4)?; // 4× the source
//! assert_eq!((up.width(), up.height()), (64, 64));
//! # Ok::<(), ifslab_strategies::Error>(())
//! ```
//!
//! ## References
//! Y. Kominami and T. Mukai, *Realtime Texture Upsampling on Graphics Hardware Using Fractal
//! Coding*, Proc. International Conference on Cyberworlds 2022, pp. 39–46,
//! doi:10.1109/CW55638.2022.00015.

pub mod baselines;
pub mod code;
pub mod decoder;
pub mod encoder;
pub mod packed;
pub mod preset;
pub mod refine;
pub mod texture;

pub use baselines::{Filter, bilinear_into, bilinear_parallel, upsample};
pub use code::FractalCode;
pub use decoder::{
    decode, decode_into, decode_serial, decode_texel, levels_for_factor, output_size,
};
pub use encoder::{
    Candidates, DistanceCentre, EncodeStats, EncoderConfig, Encoding, HALF_MAX, HALF_MIN,
    MAX_TOTAL_CANDIDATES, Matching, Reduction, SearchGrid, encode, encode_with_isa,
};
pub use packed::{CoordStorage, Manifest, PackError, PackedCode, load_dir, pack, save_dir, unpack};
pub use preset::Preset;
pub use refine::{RefineConfig, RefineReport, laplacian_variance, refine};
pub use texture::{Texture, psnr};

use crate::error::Result;

/// Encodes and then refines with `refine_cfg.passes` passes (the encoder's candidate lists
/// come from `enc_cfg`: give it β, ΔE_max and more than one candidate for the refinement to
/// have choices). Returns the encoding, with the refined code, and the refinement report.
pub fn encode_refined(
    source: &Texture,
    enc_cfg: &EncoderConfig,
    refine_cfg: &RefineConfig,
) -> Result<(Encoding, RefineReport)> {
    let mut enc = encode(source, enc_cfg)?;
    let report = refine(&mut enc.code, &enc.candidates, refine_cfg)?;
    Ok((enc, report))
}
