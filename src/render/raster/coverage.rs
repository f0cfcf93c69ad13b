//! Binary coverage buffer: one bit per sub-pixel of the `(width·s) × (height·s)` grid, row
//! by row (rows padded to whole words); an output pixel is the popcount of its `s×s` block.

use rayon::prelude::*;

use super::Accumulator;
use super::bins::TILE_BYTES;

pub(crate) struct Coverage {
    /// Padded to whole tiles.
    bits: Vec<u64>,
    s: usize,
    /// Words per sub-pixel row.
    row_words: usize,
    tile_shift: u32,
}

/// Words per sub-pixel row and `log2` of the bits per tile of a `(width·s) × (height·s)`
/// grid.
fn layout(width: u32, height: u32, s: u32) -> (u64, u32) {
    let row_words = (width as u64 * s as u64).div_ceil(64);
    let cells = row_words * 64 * height as u64 * s as u64;
    // Small buffers are one tile of at least a word.
    let tile_shift = (TILE_BYTES as u64 * 8)
        .trailing_zeros()
        .min(cells.next_power_of_two().trailing_zeros())
        .max(6);
    (row_words, tile_shift)
}

/// Bytes of one tile of the buffer [`Coverage::new`] makes.
pub(crate) fn tile_bytes(width: u32, height: u32, s: u32) -> u64 {
    (1u64 << layout(width, height, s).1) / 8
}

impl Coverage {
    pub(crate) fn new(width: u32, height: u32, s: u32) -> Self {
        let (row_words, tile_shift) = layout(width, height, s);
        let cells = row_words * 64 * height as u64 * s as u64;
        let tiles = cells.div_ceil(1 << tile_shift);
        Coverage {
            bits: vec![0; (tiles << (tile_shift - 6)) as usize],
            s: s as usize,
            row_words: row_words as usize,
            tile_shift,
        }
    }
}

/// Number of set bits in `[start, start + len)`.
fn count_bits(bits: &[u64], start: u64, len: u64) -> u32 {
    let end = start + len;
    let (mut w, last) = ((start >> 6) as usize, ((end - 1) >> 6) as usize);
    let lo_mask = !0u64 << (start & 63);
    let hi_mask = !0u64 >> (63 - ((end - 1) & 63));
    if w == last {
        return (bits[w] & lo_mask & hi_mask).count_ones();
    }
    let mut n = (bits[w] & lo_mask).count_ones();
    w += 1;
    while w < last {
        n += bits[w].count_ones();
        w += 1;
    }
    n + (bits[last] & hi_mask).count_ones()
}

impl Accumulator for Coverage {
    type Word = u64;
    const CELL_BITS: u32 = 1;
    const SUBPIXELS: bool = true;

    fn row_cells(&self) -> u64 {
        self.row_words as u64 * 64
    }

    fn tile_shift(&self) -> u32 {
        self.tile_shift
    }

    fn tile_words(&self) -> usize {
        1 << (self.tile_shift - 6)
    }

    fn words_mut(&mut self) -> &mut [u64] {
        &mut self.bits
    }

    #[inline(always)]
    fn write_tile(words: &mut [u64], offsets: &[u32]) {
        // A tile is a power of two of words: the mask keeps the offset's bits and the index
        // in bounds.
        assert!(words.len().is_power_of_two());
        let last = words.len() - 1;
        for &o in offsets {
            // SAFETY: `… & last < words.len()`.
            unsafe { *words.get_unchecked_mut((o >> 6) as usize & last) |= 1u64 << (o & 63) };
        }
    }

    fn finish(self, width: u32, height: u32) -> (Vec<f32>, u64) {
        let (w, s) = (width as usize, self.s);
        let inv = 1.0 / (s * s) as f32;
        let mut out = vec![0.0f32; w * height as usize];
        out.par_chunks_mut(w).enumerate().for_each(|(py, out_row)| {
            let mut counts = vec![0u32; w];
            for sy in 0..s {
                let row = &self.bits[(py * s + sy) * self.row_words..][..self.row_words];
                if 64 % s == 0 {
                    // Each word holds whole pixels' sub-rows: `64 / s` of them.
                    let per = 64 / s;
                    let mask = u64::MAX >> (64 - s);
                    for (j, &word) in row.iter().enumerate().filter(|(_, w)| **w != 0) {
                        for (q, c) in counts[j * per..].iter_mut().take(per).enumerate() {
                            *c += ((word >> (q * s)) & mask).count_ones();
                        }
                    }
                } else {
                    for (px, c) in counts.iter_mut().enumerate() {
                        *c += count_bits(row, (px * s) as u64, s as u64);
                    }
                }
            }
            for (o, c) in out_row.iter_mut().zip(counts) {
                *o = c as f32 * inv;
            }
        });
        (out, 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn count_bits_matches_naive() {
        let bits = vec![
            0xF0F0_1234_5678_9ABCu64,
            0xFFFF_0000_FFFF_0001,
            0x8000_0000_0000_0001,
        ];
        let naive = |s: u64, l: u64| {
            (s..s + l)
                .filter(|b| bits[(b >> 6) as usize] >> (b & 63) & 1 == 1)
                .count() as u32
        };
        for s in 0..150 {
            for l in 1..(192 - s).min(100) {
                assert_eq!(count_bits(&bits, s, l), naive(s, l), "start {s} len {l}");
            }
        }
    }
}
