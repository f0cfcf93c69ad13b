//! The fractal code of a texture: the reduced texture R, the coordinate texture C and the
//! offset texture O, all at R's resolution.
//!
//! For a texel c of R, the source's 2×2 range block at 2c is approximated by the 2×2 block of
//! R whose top-left texel is C(c) (the *virtual range*), plus the per-channel offset O(c):
//! `S(2c + δ) ≈ R(C(c) + δ) + O(c)` for δ ∈ {0, 1}².

use crate::error::{Error, Result};
use crate::problems::fractal_coding::texture::Texture;

/// Largest magnitude of a value of R or O: far beyond any grey level, and small enough that a
/// decoded texel (a sum of at most 64 of them) is always finite.
pub const MAX_MAGNITUDE: f32 = 1e9;

/// Whether a value of R or O is finite and within [`MAX_MAGNITUDE`].
fn in_range(v: f32) -> bool {
    v.is_finite() && v.abs() <= MAX_MAGNITUDE
}

/// A texture's fractal code (R, C, O).
#[derive(Clone, Debug, PartialEq)]
pub struct FractalCode {
    reduced: Texture,
    coords: Vec<u32>,
    offsets: Vec<f32>,
}

impl FractalCode {
    /// A code from its three parts. `coords[c]` is the row-major index into R of the top-left
    /// texel of c's virtual range block (so the block must fit: x ≤ width − 2, y ≤ height − 2);
    /// `offsets` holds one value per texel and channel, interleaved like R.
    pub fn new(reduced: Texture, coords: Vec<u32>, offsets: Vec<f32>) -> Result<Self> {
        let (w, h, ch) = (reduced.width(), reduced.height(), reduced.channels());
        if w < 2 || h < 2 {
            return Err(Error::InvalidInput(format!(
                "the reduced texture must be at least 2×2 to hold a 2×2 block, got {w}×{h}"
            )));
        }
        if w * h > u32::MAX as usize / 2 {
            return Err(Error::InvalidInput(format!(
                "a {w}×{h} reduced texture is too large to index with 32 bits"
            )));
        }
        if coords.len() != w * h {
            return Err(Error::InvalidInput(format!(
                "{} coordinates for a {w}×{h} reduced texture",
                coords.len()
            )));
        }
        if offsets.len() != w * h * ch {
            return Err(Error::InvalidInput(format!(
                "{} offsets for a {w}×{h} reduced texture with {ch} channel(s)",
                offsets.len()
            )));
        }
        for (c, &k) in coords.iter().enumerate() {
            let (x, y) = (k as usize % w, k as usize / w);
            if x + 1 >= w || y + 1 >= h {
                return Err(Error::InvalidInput(format!(
                    "texel ({}, {}) points at a block at ({x}, {y}) that leaves the {w}×{h} reduced texture",
                    c % w,
                    c / w
                )));
            }
        }
        if let Some(i) = offsets.iter().position(|v| !in_range(*v)) {
            return Err(Error::InvalidInput(format!(
                "offset {i} is {}; offsets must be finite grey levels of magnitude ≤ {MAX_MAGNITUDE:e}",
                offsets[i]
            )));
        }
        if let Some(i) = reduced.data().iter().position(|v| !in_range(*v)) {
            return Err(Error::InvalidInput(format!(
                "reduced texture value {i} is {}; values must be grey levels of magnitude ≤ {MAX_MAGNITUDE:e}",
                reduced.data()[i]
            )));
        }
        Ok(FractalCode {
            reduced,
            coords,
            offsets,
        })
    }

    /// The reduced texture R.
    pub fn reduced(&self) -> &Texture {
        &self.reduced
    }

    /// Absolute coordinates C: for each texel of R, the row-major index of its block's top-left texel.
    pub fn coords(&self) -> &[u32] {
        &self.coords
    }

    /// Offsets O, one per texel and channel.
    pub fn offsets(&self) -> &[f32] {
        &self.offsets
    }

    /// Width of R (half the source width).
    pub fn width(&self) -> usize {
        self.reduced.width()
    }

    /// Height of R (half the source height).
    pub fn height(&self) -> usize {
        self.reduced.height()
    }

    /// Channels per texel.
    pub fn channels(&self) -> usize {
        self.reduced.channels()
    }

    /// The source size the code reconstructs at factor 1: twice R's.
    pub fn source_size(&self) -> (usize, usize) {
        (2 * self.width(), 2 * self.height())
    }

    /// The relative coordinate C(c) − c of texel `c = (x, y)`, as stored by the packed format.
    pub fn relative(&self, x: usize, y: usize) -> (i32, i32) {
        let w = self.width();
        let k = self.coords[y * w + x] as usize;
        ((k % w) as i32 - x as i32, (k / w) as i32 - y as i32)
    }

    /// Replaces the code of texel index `c` (used by the refinement).
    pub(crate) fn set(&mut self, c: usize, coord: u32, offsets: &[f32]) {
        let ch = self.channels();
        self.coords[c] = coord;
        self.offsets[c * ch..(c + 1) * ch].copy_from_slice(offsets);
    }

    /// The parts, consumed.
    pub fn into_parts(self) -> (Texture, Vec<u32>, Vec<f32>) {
        (self.reduced, self.coords, self.offsets)
    }
}
