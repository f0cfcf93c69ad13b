//! Hit counts per output pixel, log tone-mapped at the end.

use rayon::prelude::*;

use super::Accumulator;
use super::bins::TILE_BYTES;

pub(crate) struct Density {
    /// Padded to whole tiles.
    counts: Vec<u32>,
    width: u64,
    pixels: usize,
    tile_shift: u32,
}

/// `log2` of the counts per tile of `pixels` counts.
fn tile_shift(pixels: usize) -> u32 {
    (TILE_BYTES / 4)
        .trailing_zeros()
        .min(pixels.next_power_of_two().trailing_zeros())
}

/// Bytes of one tile of the buffer [`Density::new`] makes.
pub(crate) fn tile_bytes(width: u32, height: u32) -> u64 {
    4u64 << tile_shift(width as usize * height as usize)
}

impl Density {
    pub(crate) fn new(width: u32, height: u32) -> Self {
        let pixels = width as usize * height as usize;
        let tile_shift = tile_shift(pixels);
        Density {
            counts: vec![0; pixels.div_ceil(1 << tile_shift) << tile_shift],
            width: width as u64,
            pixels,
            tile_shift,
        }
    }
}

impl Accumulator for Density {
    type Word = u32;
    const CELL_BITS: u32 = 32;
    const SUBPIXELS: bool = false;

    fn row_cells(&self) -> u64 {
        self.width
    }

    fn tile_shift(&self) -> u32 {
        self.tile_shift
    }

    fn tile_words(&self) -> usize {
        1 << self.tile_shift
    }

    fn words_mut(&mut self) -> &mut [u32] {
        &mut self.counts
    }

    #[inline(always)]
    fn write_tile(counts: &mut [u32], offsets: &[u32]) {
        // A tile is a power of two of counts: the mask keeps the offset's bits.
        let last = counts.len() - 1;
        for &o in offsets {
            let c = &mut counts[o as usize & last];
            *c = c.saturating_add(1);
        }
    }

    fn finish(self, _width: u32, _height: u32) -> (Vec<f32>, u64) {
        let counts = &self.counts[..self.pixels];
        let max = counts.iter().copied().max().unwrap_or(0);
        if max == 0 {
            return (vec![0.0; counts.len()], 0);
        }
        let norm = 1.0 / (1.0 + max as f64).ln();
        let values = counts
            .par_iter()
            .map(|&c| ((1.0 + c as f64).ln() * norm) as f32)
            .collect();
        (values, max as u64)
    }
}
