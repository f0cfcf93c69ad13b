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

impl Density {
    pub(crate) fn new(width: u32, height: u32) -> Self {
        let pixels = width as usize * height as usize;
        let tile_shift = (TILE_BYTES / 4)
            .trailing_zeros()
            .min(pixels.next_power_of_two().trailing_zeros());
        Density {
            counts: vec![0; pixels.div_ceil(1 << tile_shift) << tile_shift],
            width: width as u64,
            pixels,
            tile_shift,
        }
    }
}

impl Accumulator for Density {
    const CELL_BITS: u32 = 32;
    const SUBPIXELS: bool = false;

    fn row_cells(&self) -> u64 {
        self.width
    }

    fn tile_shift(&self) -> u32 {
        self.tile_shift
    }

    fn tiles(&self) -> usize {
        self.counts.len() >> self.tile_shift
    }

    fn write_tile(&mut self, tile: usize, offsets: &[u32]) {
        let n = 1usize << self.tile_shift;
        let counts = &mut self.counts[tile * n..(tile + 1) * n];
        for &o in offsets {
            let c = &mut counts[o as usize];
            *c = c.saturating_add(1);
        }
    }

    fn merge(&mut self, other: Self) {
        self.counts
            .par_iter_mut()
            .zip(other.counts.par_iter())
            .for_each(|(a, b)| *a = a.saturating_add(*b));
    }

    fn finish(self, _width: u32, _height: u32) -> Vec<f32> {
        let counts = &self.counts[..self.pixels];
        let max = counts.iter().copied().max().unwrap_or(0);
        if max == 0 {
            return vec![0.0; counts.len()];
        }
        let norm = 1.0 / (1.0 + max as f64).ln();
        counts
            .par_iter()
            .map(|&c| ((1.0 + c as f64).ln() * norm) as f32)
            .collect()
    }
}
