//! The decoder: recursive fractal decoding, one output texel at a time.
//!
//! An output 2ⁿ times the size of R (the source size times `factor` = 2ⁿ⁻¹) has texels
//! p = 2ⁿ·c₀ + Σᵢ 2ⁿ⁻ⁱ·Δᵢ with c₀ a texel of R and Δᵢ ∈ {0, 1}² the binary digits of p below
//! c₀. Following the chain c_i = C(c_{i−1}) + Δ_i,
//!
//! T_n(p) = R(c_n) + Σ_{i<n} O(c_i),
//!
//! so a texel costs n look-ups of (C, O) and one of R, reads only the code, and never another
//! output texel: texels can be computed in any order or in parallel with identical results.
//! At n = 1 (factor 1) this is the reconstruction of the source from R,
//! T_1(2c + δ) = R(C(c) + δ) + O(c).
//!
//! Rows are decoded in parallel with rayon, each texel walking its own chain (the loop is
//! specialised for n ≤ 8, i.e. factors up to 128, so that it unrolls). Each texel's arithmetic
//! is the same on every path (the sum is accumulated in the order i = 0, 1, …, n − 1 and
//! R(c_n) added last), so the output does not depend on the order of evaluation.

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::problems::fractal_coding::code::FractalCode;
use crate::problems::fractal_coding::texture::Texture;

/// Largest output this decoder builds (values, all channels).
const MAX_OUTPUT_VALUES: usize = 1 << 32;

/// The recursion depth n for an output `factor` times the source size: n = log₂(factor) + 1.
/// Refuses a factor that is not a power of two.
pub fn levels_for_factor(factor: u32) -> Result<u32> {
    if factor == 0 || !factor.is_power_of_two() {
        return Err(Error::param(
            "factor",
            format!("must be a power of two (1, 2, 4, 8, …), got {factor}"),
        ));
    }
    Ok(factor.trailing_zeros() + 1)
}

/// (n, width, height) of the output at `factor`, refusing outputs too large to build.
pub fn output_size(code: &FractalCode, factor: u32) -> Result<(u32, usize, usize)> {
    let n = levels_for_factor(factor)?;
    let (w, h) = ((code.width() as u128) << n, (code.height() as u128) << n);
    if w * h * code.channels() as u128 > MAX_OUTPUT_VALUES as u128 {
        return Err(Error::param(
            "factor",
            format!(
                "{factor}× of a {}×{} source would be {w}×{h} texels, more than this decoder builds",
                2 * code.width(),
                2 * code.height(),
            ),
        ));
    }
    Ok((n, w as usize, h as usize))
}

/// Upsamples by `factor` (a power of two; 1 reconstructs the source from R), in parallel.
pub fn decode(code: &FractalCode, factor: u32) -> Result<Texture> {
    let (_, w, h) = output_size(code, factor)?;
    let ch = code.channels();
    let mut data = vec![0.0f32; w * h * ch];
    decode_into(code, factor, &mut data)?;
    // Finite: every value is a sum of at most 33 code values of magnitude ≤ 1e9.
    Ok(Texture::from_trusted(w, h, ch, data))
}

/// Decodes into a caller's buffer of `width × height × channels` values (row-major,
/// interleaved), e.g. one reused frame after frame.
pub fn decode_into(code: &FractalCode, factor: u32, out: &mut [f32]) -> Result<()> {
    let (n, w, h) = output_size(code, factor)?;
    let ch = code.channels();
    if out.len() != w * h * ch {
        return Err(Error::InvalidInput(format!(
            "output buffer of {} values for a {w}×{h}×{ch} output",
            out.len()
        )));
    }
    if ch == 1 {
        decode_rows(&Nodes::<1>::new(code), n, w, out);
    } else {
        decode_rows(&Nodes::<3>::new(code), n, w, out);
    }
    Ok(())
}

fn decode_rows<const CH: usize>(nodes: &Nodes<CH>, n: u32, w: usize, out: &mut [f32]) {
    macro_rules! fixed {
        ($($l:literal)*) => {
            match n {
                $($l => out
                    .par_chunks_mut(w * CH)
                    .enumerate()
                    .for_each(|(y, row)| decode_row_fixed::<CH, $l>(nodes, y, row)),)*
                _ => out
                    .par_chunks_mut(w * CH)
                    .enumerate()
                    .for_each(|(y, row)| decode_row(nodes, n, y, row)),
            }
        };
    }
    fixed!(1 2 3 4 5 6 7 8);
}

/// The same output computed texel by texel with the plain formula, in one thread, in a
/// scrambled order: the reference the parallel decoder is tested against.
pub fn decode_serial(code: &FractalCode, factor: u32) -> Result<Texture> {
    let (n, w, h) = output_size(code, factor)?;
    let ch = code.channels();
    let mut data = vec![0.0f32; w * h * ch];
    let total = w * h;
    // A stride coprime with the texel count visits every texel once, far from raster order.
    let mut stride = (total / 2 + 1) | 1;
    while gcd(stride, total) != 1 {
        stride += 2;
    }
    let mut p = 0usize;
    for _ in 0..total {
        let (x, y) = (p % w, p / w);
        texel_formula(code, n, x, y, &mut data[p * ch..(p + 1) * ch]);
        p = (p + stride) % total;
    }
    Ok(Texture::from_trusted(w, h, ch, data))
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// One texel of the output at `factor`: the chain of look-ups of the module docs.
pub fn decode_texel(code: &FractalCode, factor: u32, x: usize, y: usize) -> Result<Vec<f32>> {
    let (n, w, h) = output_size(code, factor)?;
    if x >= w || y >= h {
        return Err(Error::InvalidInput(format!(
            "texel ({x}, {y}) is outside the {w}×{h} output"
        )));
    }
    let mut out = vec![0.0; code.channels()];
    texel_formula(code, n, x, y, &mut out);
    Ok(out)
}

/// T_n(p) = R(c_n) + Σ_{i<n} O(c_i), written as plainly as possible.
fn texel_formula(code: &FractalCode, n: u32, x: usize, y: usize, out: &mut [f32]) {
    let wr = code.width();
    let ch = code.channels();
    let (coords, offsets, r) = (code.coords(), code.offsets(), code.reduced().data());
    let mut c = (y >> n) * wr + (x >> n);
    let mut acc = [0.0f32; 3];
    for level in 1..=n {
        // O(c_{level−1}) joins the sum, then c_level = C(c_{level−1}) + Δ_level.
        for k in 0..ch {
            acc[k] += offsets[c * ch + k];
        }
        let shift = n - level;
        c = coords[c] as usize + ((x >> shift) & 1) + ((y >> shift) & 1) * wr;
    }
    for k in 0..ch {
        out[k] = acc[k] + r[c * ch + k];
    }
}

/// The code interleaved per texel for the decoder's look-ups: one load brings a texel's
/// coordinate and offsets (8 bytes a node for grey, 16 for RGB).
///
/// Invariant (checked in [`Nodes::new`]): every coordinate k satisfies k + 1 + wr < wr·hr,
/// so every chain index c_i = k + Δx + Δy·wr stays inside the node and R arrays.
struct Nodes<const CH: usize> {
    wr: usize,
    /// (C(c), O(c)) per texel of R.
    nodes: Vec<(u32, [f32; CH])>,
    /// R, `CH` values per texel.
    r: Vec<f32>,
}

impl<const CH: usize> Nodes<CH> {
    fn new(code: &FractalCode) -> Self {
        assert_eq!(
            code.channels(),
            CH,
            "node width must match the code's channels"
        );
        let (wr, len) = (code.width(), code.width() * code.height());
        let nodes: Vec<(u32, [f32; CH])> = code
            .coords()
            .iter()
            .enumerate()
            .map(|(c, &k)| {
                let o: [f32; CH] = code.offsets()[c * CH..(c + 1) * CH]
                    .try_into()
                    .expect("CH offsets per texel");
                (k, o)
            })
            .collect();
        let r = code.reduced().data().to_vec();
        // FractalCode::new already refuses blocks that leave R; the unchecked look-ups of
        // the decoder rely on it, so it is re-checked here, next to them.
        assert!(
            nodes.len() == len
                && r.len() == len * CH
                && nodes.iter().all(|&(k, _)| k as usize + 1 + wr < len),
            "a fractal code with a block outside R reached the decoder"
        );
        Nodes { wr, nodes, r }
    }

    /// The node of texel `c`.
    #[inline(always)]
    fn node(&self, c: usize) -> (u32, [f32; CH]) {
        debug_assert!(c < self.nodes.len());
        // SAFETY: callers pass c = c₀ < wr·hr (a texel of R) or c = k + Δx + Δy·wr with k a
        // coordinate of this code and Δ ∈ {0, 1}², which the invariant of `new` keeps below
        // wr·hr = nodes.len().
        unsafe { *self.nodes.get_unchecked(c) }
    }

    /// Channel `j` of R at texel `c` (same bound as [`Nodes::node`]; j < CH).
    #[inline(always)]
    fn r(&self, c: usize, j: usize) -> f32 {
        debug_assert!(c * CH + j < self.r.len());
        // SAFETY: c < wr·hr as in `node`, j < CH, and r holds wr·hr·CH values.
        unsafe { *self.r.get_unchecked(c * CH + j) }
    }
}

/// Digit offsets of row `y`: the vertical part of Δ at each level, as an index step.
fn row_digits(wr: usize, n: u32, y: usize) -> [usize; 32] {
    let mut dy = [0usize; 32];
    for (shift, d) in dy.iter_mut().enumerate().take(n as usize) {
        *d = ((y >> shift) & 1) * wr;
    }
    dy
}

/// A row of the output for n = N known at compile time (the chain loop unrolls).
fn decode_row_fixed<const CH: usize, const N: usize>(nodes: &Nodes<CH>, y: usize, row: &mut [f32]) {
    let wr = nodes.wr;
    let all = row_digits(wr, N as u32, y);
    let dy: [usize; N] = std::array::from_fn(|s| all[s]);
    let row0 = (y >> N) * wr;
    for (x, out) in row.chunks_exact_mut(CH).enumerate() {
        let mut c = row0 + (x >> N);
        let mut acc = [0.0f32; CH];
        for shift in (0..N).rev() {
            let (k, o) = nodes.node(c);
            for j in 0..CH {
                acc[j] += o[j];
            }
            c = k as usize + ((x >> shift) & 1) + dy[shift];
        }
        for j in 0..CH {
            out[j] = acc[j] + nodes.r(c, j);
        }
    }
}

/// A row of the output for any n.
fn decode_row<const CH: usize>(nodes: &Nodes<CH>, n: u32, y: usize, row: &mut [f32]) {
    let wr = nodes.wr;
    let dy = row_digits(wr, n, y);
    let row0 = (y >> n) * wr;
    for (x, out) in row.chunks_exact_mut(CH).enumerate() {
        let mut c = row0 + (x >> n);
        let mut acc = [0.0f32; CH];
        for shift in (0..n as usize).rev() {
            let (k, o) = nodes.node(c);
            for j in 0..CH {
                acc[j] += o[j];
            }
            c = k as usize + ((x >> shift) & 1) + dy[shift];
        }
        for j in 0..CH {
            out[j] = acc[j] + nodes.r(c, j);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factors_must_be_powers_of_two() {
        assert_eq!(levels_for_factor(1).unwrap(), 1);
        assert_eq!(levels_for_factor(8).unwrap(), 4);
        assert!(levels_for_factor(0).is_err());
        assert!(levels_for_factor(6).is_err());
    }
}
